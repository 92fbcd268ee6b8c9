// horus-check: what only a compiler front end can see in a HORUS user's C++ code (see README.md).
//
// Runs Clang over the translation units of a compile_commands.json and reports, compiler-style:
//   1. nodes whose publishers()/subscribers() disagree with the topics their code opens;
//   2. calls that sleep, lock, block, allocate or do I/O reached from tick() of a node with a rate
//      or budget (following calls into functions the translation unit defines);
//   3. generated POD messages whose record layout differs on another target triple.
// Facts are gathered per translation unit and judged once all are read: a generated node base
// declares its topic lists in the package's _nodes.cpp while the user's node lives in main.cpp.
#include <clang/AST/ASTConsumer.h>
#include <clang/AST/ASTContext.h>
#include <clang/AST/DeclCXX.h>
#include <clang/AST/DeclTemplate.h>
#include <clang/AST/ExprCXX.h>
#include <clang/AST/RecordLayout.h>
#include <clang/AST/RecursiveASTVisitor.h>
#include <clang/Basic/SourceManager.h>
#include <clang/Basic/TargetInfo.h>
#include <clang/Frontend/ASTUnit.h>
#include <clang/Frontend/CompilerInstance.h>
#include <clang/Frontend/FrontendAction.h>
#include <clang/Tooling/ArgumentsAdjusters.h>
#include <clang/Tooling/CommonOptionsParser.h>
#include <clang/Tooling/Tooling.h>
#include <llvm/Support/CommandLine.h>
#include <llvm/Support/FormatVariadic.h>
#include <llvm/Support/JSON.h>
#include <llvm/Support/raw_ostream.h>

#include <algorithm>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#ifndef HORUS_CHECK_RESOURCE_DIR
#error "HORUS_CHECK_RESOURCE_DIR (clang's resource directory) must be defined by the build"
#endif

namespace {

using namespace clang;

llvm::cl::OptionCategory check_category("horus-check options");
llvm::cl::opt<bool> json_output("json", llvm::cl::desc("Print the findings and nodes as JSON"),
                                llvm::cl::cat(check_category));
llvm::cl::list<std::string> layout_targets(
    "target",
    llvm::cl::desc("Compare generated POD layouts with this target triple (repeatable), "
                   "e.g. aarch64-linux-gnu, armv7-linux-gnueabihf, i686-linux-gnu"),
    llvm::cl::cat(check_category));
llvm::cl::opt<bool> lint_all_nodes(
    "all-nodes", llvm::cl::desc("Lint tick() of every node, not only nodes with a rate or budget"),
    llvm::cl::cat(check_category));

struct Location {
  std::string file;
  unsigned line = 0;
  unsigned column = 0;
  auto key() const { return std::tie(file, line, column); }
  bool operator<(const Location& other) const { return key() < other.key(); }
};

struct Finding {
  Location where;
  std::string check;
  std::string message;
  std::string node;                // empty for layout findings
  std::vector<std::string> chain;  // tick() findings: the calls from tick() to the offending one
  auto key() const { return std::tie(where, check, node, message); }
  bool operator<(const Finding& other) const { return key() < other.key(); }
};

struct OpenedTopic {
  std::string member;
  std::optional<std::string> name;  // empty when the name is computed at run time
  std::string type;                 // canonical spelling of T in Topic<T>
  Location where;
};

struct DeclaredTopic {
  std::string name;
  std::string type;  // canonical spelling of T in TypeInfo<T>::name, empty when not known
  Location where;
};

// What a TU shows of one class derived from horus::Node, merged over all TUs by qualified name.
struct NodeFacts {
  Location where;
  std::vector<std::string> bases;               // direct bases that are nodes
  std::map<std::string, OpenedTopic> topics;    // by member name
  std::map<std::string, OpenedTopic> services;  // ServiceClient / ServiceServer members
  std::map<std::string, Location> sent;         // member -> first send()/loan()/publish()
  std::map<std::string, Location> received;     // member -> first try_recv()/recv()/read_latest()
  bool overrides_publishers = false, overrides_subscribers = false;
  std::optional<std::vector<DeclaredTopic>> publishers, subscribers;  // once a body is seen
  std::string realtime_reason;  // "rate", "budget", "deadline" when declared or configured
  std::set<Finding> tick_findings;
};

std::map<std::string, NodeFacts> nodes;
std::set<Finding> findings;
std::set<std::pair<std::string, std::string>> layouts_checked;  // (record, triple)

Location location_of(const SourceManager& sources, SourceLocation loc) {
  const PresumedLoc presumed = sources.getPresumedLoc(sources.getExpansionLoc(loc));
  if (presumed.isInvalid()) return {};
  return {presumed.getFilename(), presumed.getLine(), presumed.getColumn()};
}

bool in_namespace(const Decl* decl, llvm::StringRef name) {
  for (const DeclContext* context = decl->getDeclContext(); context != nullptr;
       context = context->getParent()) {
    if (const auto* ns = dyn_cast<NamespaceDecl>(context)) {
      if (ns->getName() == name && ns->getParent()->getRedeclContext()->isTranslationUnit())
        return true;
    }
  }
  return false;
}

bool is_horus_class(const CXXRecordDecl* record, llvm::StringRef name) {
  return record != nullptr && record->getName() == name && in_namespace(record, "horus");
}

bool is_std_class(const CXXRecordDecl* record, std::initializer_list<llvm::StringRef> names) {
  if (record == nullptr || !in_namespace(record, "std")) return false;
  return std::find(names.begin(), names.end(), record->getName()) != names.end();
}

const CXXRecordDecl* record_of(QualType type) {
  return type.isNull() ? nullptr : type.getNonReferenceType()->getAsCXXRecordDecl();
}

bool derives_from_node(const CXXRecordDecl* record, int depth = 0) {
  if (record == nullptr || !record->hasDefinition() || depth > 64) return false;
  for (const auto& base : record->getDefinition()->bases()) {
    const CXXRecordDecl* base_record = record_of(base.getType());  // null when dependent
    if (is_horus_class(base_record, "Node") || derives_from_node(base_record, depth + 1))
      return true;
  }
  return false;
}

std::string canonical(QualType type) {
  PrintingPolicy policy{LangOptions{}};
  policy.SuppressScope = false;
  policy.FullyQualifiedName = true;
  return type.getCanonicalType().getUnqualifiedType().getAsString(policy);
}

// What a conversion, temporary or constructor call (its first argument) is made from, or null.
const Expr* converted_from(const Expr* expr) {
  if (const auto* construct = dyn_cast<CXXConstructExpr>(expr))
    return construct->getNumArgs() > 0 ? construct->getArg(0) : nullptr;
  if (const auto* temporary = dyn_cast<MaterializeTemporaryExpr>(expr))
    return temporary->getSubExpr();
  if (const auto* bind = dyn_cast<CXXBindTemporaryExpr>(expr)) return bind->getSubExpr();
  if (const auto* cleanups = dyn_cast<ExprWithCleanups>(expr)) return cleanups->getSubExpr();
  if (const auto* cast = dyn_cast<CastExpr>(expr)) return cast->getSubExpr();
  if (const auto* paren = dyn_cast<ParenExpr>(expr)) return paren->getSubExpr();
  return nullptr;
}

// The string an expression spells when it is a literal or a constant initialised by one,
// through the conversions to std::string / std::string_view.
std::optional<std::string> constant_string(const Expr* expr) {
  for (int depth = 0; expr != nullptr && depth < 32; ++depth) {
    expr = expr->IgnoreParenImpCasts();
    if (const auto* literal = dyn_cast<StringLiteral>(expr)) return literal->getString().str();
    if (const auto* list = dyn_cast<InitListExpr>(expr); list && list->getNumInits() == 1) {
      expr = list->getInit(0);
    } else if (const auto* ref = dyn_cast<DeclRefExpr>(expr)) {
      const auto* var = dyn_cast<VarDecl>(ref->getDecl());
      const Expr* init = var != nullptr ? var->getAnyInitializer() : nullptr;
      if (init == nullptr || !var->getType().isConstQualified()) return std::nullopt;
      expr = init;
    } else {
      expr = converted_from(expr);
    }
  }
  return std::nullopt;
}

// The T of a `horus::TypeInfo<T>::name` reference inside `expr`, canonically spelled.
std::string typeinfo_type(const Expr* expr) {
  struct Finder : RecursiveASTVisitor<Finder> {
    std::string type;
    bool VisitDeclRefExpr(DeclRefExpr* ref) {
      const auto* info =
          dyn_cast<ClassTemplateSpecializationDecl>(ref->getDecl()->getDeclContext());
      if (info != nullptr && is_horus_class(info, "TypeInfo") && info->getTemplateArgs().size() > 0)
        type = canonical(info->getTemplateArgs()[0].getAsType());
      return type.empty();
    }
  } finder;
  finder.TraverseStmt(const_cast<Expr*>(expr));
  return finder.type;
}

std::vector<DeclaredTopic> declared_topics(const Stmt* body, const SourceManager& sources) {
  struct Finder : RecursiveASTVisitor<Finder> {
    const SourceManager* sources = nullptr;
    std::vector<DeclaredTopic> topics;
    bool VisitInitListExpr(InitListExpr* list) {
      // The visitor shows the list as written (its syntactic form): a semantic form that has one is
      // the same list again.
      if ((list->isSemanticForm() && list->getSyntacticForm() != nullptr) ||
          !is_horus_class(record_of(list->getType()), "TopicMetadata") || list->getNumInits() < 1)
        return true;
      if (auto name = constant_string(list->getInit(0))) {
        topics.push_back({*name, list->getNumInits() > 1 ? typeinfo_type(list->getInit(1)) : "",
                          location_of(*sources, list->getBeginLoc())});
      }
      return true;
    }
  } finder;
  finder.sources = &sources;
  finder.TraverseStmt(const_cast<Stmt*>(body));
  return finder.topics;
}

// The most derived node class among the smart pointers an argument converts from
// (`add(std::make_unique<Lidar>(...))` adds a Lidar through a shared_ptr<Node>).
const CXXRecordDecl* node_class_of_argument(const Expr* expr) {
  const CXXRecordDecl* found = nullptr;
  for (int depth = 0; expr != nullptr && depth < 32; ++depth, expr = converted_from(expr)) {
    const auto* pointer =
        dyn_cast_or_null<ClassTemplateSpecializationDecl>(record_of(expr->getType()));
    if (pointer != nullptr && is_std_class(pointer, {"shared_ptr", "unique_ptr"}) &&
        pointer->getTemplateArgs().size() > 0) {
      const auto* pointee = record_of(pointer->getTemplateArgs()[0].getAsType());
      if (derives_from_node(pointee)) found = pointee;
    }
  }
  return found;
}

// The qualified name as a reader would write it (without "(anonymous namespace)::").
std::string qualified(const NamedDecl* decl) {
  std::string name = decl->getQualifiedNameAsString();
  const std::string anonymous = "(anonymous namespace)::";
  for (auto at = name.find(anonymous); at != std::string::npos; at = name.find(anonymous))
    name.erase(at, anonymous.size());
  return name;
}

/// A type the runtime defines itself: directly in namespace horus, or in horus::detail.
bool is_runtime_type(const NamedDecl* decl) {
  const std::string name = qualified(decl);
  if (name.rfind("horus::", 0) != 0) return false;
  const std::string rest = name.substr(7);
  return rest.find("::") == std::string::npos || rest.rfind("detail::", 0) == 0;
}

// Names a callee for a call chain: `fill_buffer`, `Worker::step`, `std::vector::push_back`.
std::string callee_name(const FunctionDecl* function) {
  if (const auto* method = dyn_cast<CXXMethodDecl>(function)) {
    if (method->getParent()->isLambda()) return "lambda";
    return qualified(method->getParent()) + "::" + method->getNameAsString();
  }
  return qualified(function);
}

// Why a call has no place on a real-time path, or nothing: {check, what}.
std::optional<std::pair<std::string, std::string>> classify_call(const FunctionDecl* function,
                                                                 const CallExpr* call) {
  const std::string name = function->getNameAsString();
  const auto* method = dyn_cast<CXXMethodDecl>(function);
  const CXXRecordDecl* owner = method != nullptr ? method->getParent() : nullptr;
  const bool global_c = function->getDeclContext()->getRedeclContext()->isTranslationUnit() ||
                        (in_namespace(function, "std") && owner == nullptr);
  static const std::set<std::string> sleeps{"sleep", "usleep", "nanosleep", "clock_nanosleep"};
  static const std::set<std::string> allocations{
      "malloc", "calloc",      "realloc",     "aligned_alloc",  "posix_memalign",
      "strdup", "make_shared", "make_unique", "allocate_shared"};
  static const std::set<std::string> c_io{
      "printf", "fprintf", "vprintf", "vfprintf", "puts",   "fputs", "putchar", "fputc",  "putc",
      "fwrite", "fread",   "fopen",   "fclose",   "fflush", "fgets", "fgetc",   "getc",   "getchar",
      "scanf",  "fscanf",  "perror",  "open",     "read",   "write", "fsync",   "getline"};
  static const std::set<std::string> growing{
      "push_back", "emplace_back", "push_front",  "emplace_front",    "insert",
      "emplace",   "emplace_hint", "try_emplace", "insert_or_assign", "resize",
      "reserve",   "append",       "operator+=",  "assign",           "push"};

  if (name == "sleep_for" || name == "sleep_until") {
    if (in_namespace(function, "std"))
      return {{"horus-rt-sleep", "sleeps (std::this_thread::" + name + ")"}};
  }
  if (global_c && sleeps.count(name) != 0) return {{"horus-rt-sleep", "sleeps (" + name + ")"}};
  if (global_c && (name == "pthread_mutex_lock" || name == "pthread_cond_wait"))
    return {{"horus-rt-lock", "locks (" + name + ")"}};
  if (owner != nullptr &&
      is_std_class(owner, {"mutex", "timed_mutex", "recursive_mutex", "recursive_timed_mutex",
                           "shared_mutex", "shared_timed_mutex", "unique_lock", "shared_lock"}) &&
      (name == "lock" || name == "lock_shared" || name.rfind("try_lock_", 0) == 0))
    return {{"horus-rt-lock", "locks a mutex (" + callee_name(function) + ")"}};
  if (owner != nullptr && is_std_class(owner, {"condition_variable", "condition_variable_any"}) &&
      name.rfind("wait", 0) == 0)
    return {{"horus-rt-lock", "waits on a condition variable (" + callee_name(function) + ")"}};
  if (owner != nullptr && is_horus_class(owner, "Topic") && name == "recv")
    return {{"horus-rt-block", "blocks in Topic::recv(timeout) (use try_recv())"}};
  if (owner != nullptr && is_horus_class(owner, "ServiceClient") && name.rfind("call", 0) == 0)
    return {{"horus-rt-block", "blocks waiting for a service reply (ServiceClient::" + name + ")"}};
  if ((global_c || in_namespace(function, "std")) && owner == nullptr &&
      allocations.count(name) != 0)
    return {{"horus-rt-alloc", "allocates (" + callee_name(function) + ")"}};
  if (owner != nullptr && in_namespace(owner, "std") && growing.count(name) != 0 &&
      is_std_class(owner,
                   {"vector", "basic_string", "deque", "list", "forward_list", "map", "multimap",
                    "set", "multiset", "unordered_map", "unordered_multimap", "unordered_set",
                    "unordered_multiset", "queue", "stack", "priority_queue"}))
    return {{"horus-rt-alloc",
             "allocates: grows a std::" + owner->getNameAsString() + " (" + name + ")"}};
  if (owner != nullptr && name == "operator[]" && is_std_class(owner, {"map", "unordered_map"}))
    return {{"horus-rt-alloc",
             "allocates: std::" + owner->getNameAsString() + "::operator[] inserts missing keys"}};
  if (global_c && c_io.count(name) != 0) return {{"horus-rt-io", "does I/O (" + name + ")"}};
  const bool stream_operator = name == "operator<<" || name == "operator>>";
  if (stream_operator && call != nullptr && call->getNumArgs() > 0 &&
      in_namespace(function, "std")) {
    const Expr* stream = call->getArg(0)->IgnoreParenImpCasts();
    // `std::cout << a << b`: the stream is the innermost left operand.
    while (const auto* inner = dyn_cast<CXXOperatorCallExpr>(stream)) {
      if (inner->getNumArgs() == 0 ||
          (inner->getOperator() != OO_LessLess && inner->getOperator() != OO_GreaterGreater))
        break;
      stream = inner->getArg(0)->IgnoreParenImpCasts();
    }
    if (const auto* ref = dyn_cast<DeclRefExpr>(stream)) {
      const std::string stream_name = ref->getDecl()->getNameAsString();
      if (in_namespace(ref->getDecl(), "std") &&
          (stream_name == "cout" || stream_name == "cerr" || stream_name == "clog"))
        return {{"horus-rt-io", "writes to std::" + stream_name}};
    }
    if (is_std_class(record_of(stream->getType()),
                     {"basic_ostream", "basic_istream", "basic_ofstream", "basic_ifstream",
                      "basic_fstream", "basic_iostream"}))
      return {{"horus-rt-io", "does stream I/O (" + name + ")"}};
  }
  if (owner != nullptr && is_std_class(owner, {"basic_ostream", "basic_istream", "basic_ofstream",
                                               "basic_ifstream", "basic_fstream", "basic_filebuf"}))
    return {{"horus-rt-io", "does stream I/O (" + callee_name(function) + ")"}};
  return std::nullopt;
}

// Walks tick() and every function it calls that this TU defines (outside std and horus).
class TickLinter {
 public:
  TickLinter(const SourceManager& sources, NodeFacts& node, std::string node_name)
      : sources_(sources), node_(node), node_name_(std::move(node_name)) {}

  void lint(const FunctionDecl* tick) {
    chain_.push_back(callee_name(tick));
    walk(tick);
  }

 private:
  struct Walker : RecursiveASTVisitor<Walker> {
    TickLinter* linter = nullptr;
    bool shouldVisitLambdaBody() const { return false; }  // a lambda runs when it is called
    bool VisitCXXNewExpr(CXXNewExpr* expr) {
      linter->report(expr->getBeginLoc(), "horus-rt-alloc", "allocates (new)", "operator new");
      return true;
    }
    bool VisitCXXConstructExpr(CXXConstructExpr* expr) {
      const CXXRecordDecl* record = record_of(expr->getType());
      if (is_std_class(record, {"lock_guard", "unique_lock", "scoped_lock", "shared_lock"})) {
        linter->report(expr->getBeginLoc(), "horus-rt-lock",
                       "locks a mutex (std::" + record->getNameAsString() + ")",
                       "std::" + record->getNameAsString());
      } else if (is_std_class(record, {"basic_ofstream", "basic_ifstream", "basic_fstream"})) {
        linter->report(expr->getBeginLoc(), "horus-rt-io",
                       "opens a file (std::" + record->getNameAsString() + ")",
                       "std::" + record->getNameAsString());
      } else if (const CXXConstructorDecl* constructor = expr->getConstructor()) {
        linter->follow(constructor, expr->getBeginLoc());
      }
      return true;
    }
    bool VisitCallExpr(CallExpr* call) {
      const FunctionDecl* function = call->getDirectCallee();
      if (function == nullptr) return true;
      if (auto verdict = classify_call(function, call)) {
        linter->report(call->getBeginLoc(), verdict->first, verdict->second, callee_name(function));
      } else {
        linter->follow(function, call->getBeginLoc());
      }
      return true;
    }
  };

  void walk(const FunctionDecl* function) {
    Walker walker;
    walker.linter = this;
    walker.TraverseStmt(function->getBody());
  }

  void follow(const FunctionDecl* function, SourceLocation call_site) {
    const FunctionDecl* definition = nullptr;
    if (!function->hasBody(definition) || definition == nullptr) return;
    if (in_namespace(definition, "std") || in_namespace(definition, "horus") ||
        sources_.isInSystemHeader(sources_.getExpansionLoc(definition->getLocation())))
      return;
    if (!visiting_.insert(definition).second) return;  // recursion, or already walked on this path
    (void)call_site;
    chain_.push_back(callee_name(definition));
    walk(definition);
    chain_.pop_back();
    visiting_.erase(definition);
  }

  void report(SourceLocation loc, const std::string& check, const std::string& what,
              const std::string& callee) {
    Finding finding;
    finding.where = location_of(sources_, loc);
    finding.check = check;
    finding.node = node_name_;
    finding.chain = chain_;
    finding.chain.push_back(callee);
    std::string path;
    for (const auto& step : finding.chain) path += (path.empty() ? "" : " -> ") + step;
    finding.message = "tick() of node '" + node_name_ + "' " + what +
                      " on its real-time path; call chain: " + path;
    // One finding per call site, through the shortest chain that reaches it.
    const auto same_site = std::find_if(
        node_.tick_findings.begin(), node_.tick_findings.end(), [&](const Finding& other) {
          return other.where.key() == finding.where.key() && other.check == finding.check;
        });
    if (same_site != node_.tick_findings.end()) {
      if (same_site->chain.size() <= finding.chain.size()) return;
      node_.tick_findings.erase(same_site);
    }
    node_.tick_findings.insert(std::move(finding));
  }

  const SourceManager& sources_;
  NodeFacts& node_;
  std::string node_name_;
  std::vector<std::string> chain_;
  std::set<const FunctionDecl*> visiting_;
};

// Mirrors a record's layout in a freestanding struct of builtin types, so that Clang can lay it
// out again for another target (the real headers need that target's C++ library).
class LayoutMirror {
 public:
  explicit LayoutMirror(ASTContext& context) : context_(context) {}

  std::optional<std::string> mirror(const RecordDecl* record) {
    record = record->getDefinition();
    if (auto found = names_.find(record); found != names_.end()) return found->second;
    const auto* cxx = dyn_cast<CXXRecordDecl>(record);
    std::string bases;
    if (cxx != nullptr) {
      for (const auto& base : cxx->bases()) {
        if (base.isVirtual()) return std::nullopt;
        auto base_name = mirror(record_of(base.getType()));
        if (!base_name) return std::nullopt;
        bases += (bases.empty() ? " : " : ", ") + *base_name;
      }
    }
    std::string fields;
    for (const FieldDecl* field : record->fields()) {
      if (field->isBitField()) return std::nullopt;
      auto type = spell(field->getType());
      if (!type) return std::nullopt;
      std::string align;
      if (field->hasAttr<AlignedAttr>())
        align = "alignas(" + std::to_string(field->getMaxAlignment() / 8) + ") ";
      fields += "  " + align + *type + " f" + std::to_string(field->getFieldIndex()) + ";\n";
    }
    std::string name = "R" + std::to_string(names_.size());
    std::string align;
    if (record->hasAttr<AlignedAttr>())
      align = "alignas(" + std::to_string(record->getMaxAlignment() / 8) + ") ";
    code_ += (record->isUnion() ? "union " : "struct ") + align + name + bases + " {\n" + fields +
             "};\n";
    names_[record] = name;
    return name;
  }

  const std::string& code() const { return code_; }

 private:
  std::optional<std::string> spell(QualType type) {
    type = type.getCanonicalType().getUnqualifiedType();
    if (const auto* array = context_.getAsConstantArrayType(type)) {
      auto element = spell(array->getElementType());
      if (!element) return std::nullopt;
      std::string alias = "A" + std::to_string(aliases_++);
      code_ += "using " + alias + " = " + *element + "[" +
               std::to_string(array->getSize().getZExtValue()) + "];\n";
      return alias;
    }
    if (const auto* enumeration = type->getAs<EnumType>())
      return spell(enumeration->getDecl()->getIntegerType());
    if (type->isPointerType()) return std::string("void*");
    if (const auto* record = type->getAsRecordDecl()) return mirror(record);
    const auto* builtin = type->getAs<BuiltinType>();
    if (builtin == nullptr) return std::nullopt;
    if (builtin->isBooleanType()) return std::string("bool");
    if (builtin->getKind() == BuiltinType::Float) return std::string("float");
    if (builtin->getKind() == BuiltinType::Double) return std::string("double");
    if (builtin->getKind() == BuiltinType::LongDouble) return std::string("long double");
    if (!builtin->isInteger()) return std::nullopt;
    const std::string sign = builtin->isSignedInteger() ? "signed " : "unsigned ";
    switch (context_.getTypeSize(type)) {
      case 8:
        return sign + "char";
      case 16:
        return sign + "short";
      case 32:
        return sign + "int";
      case 64:
        return sign + "long long";
      default:
        return std::nullopt;
    }
  }

  ASTContext& context_;
  std::map<const RecordDecl*, std::string> names_;
  std::string code_;
  int aliases_ = 0;
};

std::string triple_arch(const std::string& triple) { return triple.substr(0, triple.find('-')); }

void check_layouts(ASTContext& context,
                   const std::vector<std::pair<const RecordDecl*, std::string>>& pods) {
  const std::string host = context.getTargetInfo().getTriple().str();
  const SourceManager& sources = context.getSourceManager();
  for (const std::string& triple : layout_targets) {
    LayoutMirror mirror(context);
    std::vector<std::tuple<const RecordDecl*, std::string, std::string>>
        checked;  // record, schema, mirror
    for (const auto& [record, schema] : pods) {
      if (!layouts_checked.insert({qualified(record), triple}).second) continue;
      if (auto name = mirror.mirror(record)) {
        checked.emplace_back(record, schema, *name);
      } else {
        findings.insert({location_of(sources, record->getLocation()),
                         "horus-layout",
                         "cannot mirror the layout of schema '" + schema + "' for " + triple,
                         "",
                         {}});
      }
    }
    if (checked.empty()) continue;
    std::unique_ptr<ASTUnit> unit = tooling::buildASTFromCodeWithArgs(
        mirror.code(), {"-std=c++20", "-nostdinc", "-target", triple, "-w"},
        "horus_check_layout.cpp");
    if (unit == nullptr || unit->getDiagnostics().hasErrorOccurred()) {
      llvm::errs() << "horus-check: cannot lay out the generated messages for " << triple << "\n";
      std::exit(2);
    }
    ASTContext& target = unit->getASTContext();
    std::map<std::string, const RecordDecl*> mirrored;
    for (const Decl* decl : target.getTranslationUnitDecl()->decls())
      if (const auto* record = dyn_cast<RecordDecl>(decl);
          record && record->isThisDeclarationADefinition())
        mirrored[record->getNameAsString()] = record;
    for (const auto& [record, schema, name] : checked) {
      const ASTRecordLayout& here = context.getASTRecordLayout(record);
      const ASTRecordLayout& there = target.getASTRecordLayout(mirrored.at(name));
      std::string differences;
      SourceLocation first = record->getLocation();
      bool located = false;
      for (const FieldDecl* field : record->fields()) {
        const auto index = field->getFieldIndex();
        const auto host_offset = here.getFieldOffset(index) / 8;
        const auto target_offset = there.getFieldOffset(index) / 8;
        if (host_offset == target_offset) continue;
        differences +=
            (differences.empty() ? "" : ", ") +
            ("field '" + field->getNameAsString() + "' at offset " + std::to_string(target_offset) +
             " instead of " + std::to_string(host_offset));
        if (!located) first = field->getLocation();
        located = true;
      }
      auto compare = [&](const char* what, std::int64_t host_value, std::int64_t target_value) {
        if (host_value == target_value) return;
        differences += (differences.empty() ? "" : ", ") +
                       (std::string(what) + " " + std::to_string(target_value) + " instead of " +
                        std::to_string(host_value));
      };
      compare("size", here.getSize().getQuantity(), there.getSize().getQuantity());
      compare("alignment", here.getAlignment().getQuantity(), there.getAlignment().getQuantity());
      if (differences.empty()) continue;
      findings.insert({location_of(sources, first),
                       "horus-layout",
                       "the POD layout of schema '" + schema + "' differs on " + triple + " (" +
                           triple_arch(host) + " is the reference): " + differences +
                           "; reorder the fields or pad them explicitly",
                       "",
                       {}});
    }
  }
}

class FactCollector : public RecursiveASTVisitor<FactCollector> {
 public:
  explicit FactCollector(ASTContext& context)
      : context_(context), sources_(context.getSourceManager()) {}

  bool shouldVisitTemplateInstantiations() const { return true; }

  bool VisitCXXRecordDecl(CXXRecordDecl* record) {
    if (!record->isThisDeclarationADefinition() || !derives_from_node(record) ||
        record->isDependentContext())
      return true;
    NodeFacts& node = nodes[qualified(record)];
    node.where = location_of(sources_, record->getLocation());
    node.bases.clear();
    for (const auto& base : record->bases())
      if (const auto* base_record = record_of(base.getType()); derives_from_node(base_record))
        node.bases.push_back(qualified(base_record));
    for (const FieldDecl* field : record->fields()) {
      const auto* type =
          dyn_cast_or_null<ClassTemplateSpecializationDecl>(record_of(field->getType()));
      if (type == nullptr) continue;
      const bool topic = is_horus_class(type, "Topic");
      if (!topic && !is_horus_class(type, "ServiceClient") &&
          !is_horus_class(type, "ServiceServer"))
        continue;
      OpenedTopic opened{field->getNameAsString(), std::nullopt,
                         type->getTemplateArgs().size() > 0
                             ? canonical(type->getTemplateArgs()[0].getAsType())
                             : "",
                         location_of(sources_, field->getLocation())};
      if (const Expr* init = field->getInClassInitializer()) opened_with(opened, init);
      auto& members = topic ? node.topics : node.services;
      auto [slot, added] = members.emplace(opened.member, opened);
      if (!added && opened.name) slot->second = opened;
    }
    for (const CXXConstructorDecl* constructor : record->ctors()) {
      const CXXConstructorDecl* definition =
          dyn_cast_or_null<CXXConstructorDecl>(constructor->getDefinition());
      if (definition == nullptr) continue;
      for (const CXXCtorInitializer* init : definition->inits()) {
        const FieldDecl* field = init->getMember();
        if (field == nullptr || !init->isWritten()) continue;
        for (auto* members : {&node.topics, &node.services}) {
          auto found = members->find(field->getNameAsString());
          if (found != members->end()) opened_with(found->second, init->getInit());
        }
      }
    }
    for (const CXXMethodDecl* method : record->methods()) {
      const std::string name = method->getNameAsString();
      const FunctionDecl* definition = nullptr;
      const bool has_body = method->hasBody(definition);
      if (name == "publishers" || name == "subscribers") {
        (name == "publishers" ? node.overrides_publishers : node.overrides_subscribers) = true;
        if (has_body)
          (name == "publishers" ? node.publishers : node.subscribers) =
              declared_topics(definition->getBody(), sources_);
      } else if (name == "node_config" && has_body) {
        note_config(record, definition->getBody());
      }
    }
    return true;
  }

  bool VisitCXXMethodDecl(CXXMethodDecl* method) {
    // Out-of-line definitions (generated _nodes.cpp defines publishers() outside the class).
    if (!method->isThisDeclarationADefinition() || !method->isOutOfLine()) return true;
    const CXXRecordDecl* record = method->getParent();
    if (!derives_from_node(record)) return true;
    NodeFacts& node = nodes[qualified(record)];
    const std::string name = method->getNameAsString();
    if (name == "publishers") {
      node.overrides_publishers = true;
      node.publishers = declared_topics(method->getBody(), sources_);
    } else if (name == "subscribers") {
      node.overrides_subscribers = true;
      node.subscribers = declared_topics(method->getBody(), sources_);
    } else if (name == "node_config") {
      note_config(record, method->getBody());
    }
    return true;
  }

  bool VisitCXXMemberCallExpr(CXXMemberCallExpr* call) {
    const CXXMethodDecl* method = call->getMethodDecl();
    if (method == nullptr) return true;
    const std::string name = method->getNameAsString();
    if (is_horus_class(method->getParent(), "Topic")) {
      const auto* member =
          dyn_cast<MemberExpr>(call->getImplicitObjectArgument()->IgnoreParenImpCasts());
      const auto* field =
          member != nullptr ? dyn_cast<FieldDecl>(member->getMemberDecl()) : nullptr;
      if (field == nullptr || !derives_from_node(dyn_cast<CXXRecordDecl>(field->getParent())))
        return true;
      NodeFacts& node = nodes[qualified(field->getParent())];
      const Location where = location_of(sources_, call->getExprLoc());
      if (name == "send" || name == "loan" || name == "publish")
        node.sent.emplace(field->getNameAsString(), where);
      if (name == "try_recv" || name == "recv" || name == "read_latest")
        node.received.emplace(field->getNameAsString(), where);
      return true;
    }
    // scheduler.add(node).rate(...) / RunNode(node).budget(...): a rate or budget set at the call.
    if ((name == "rate" || name == "budget" || name == "deadline") &&
        in_namespace(method->getParent(), "horus")) {
      // Down the chain of settings to the call or constructor that was given the node.
      const Expr* object = call->getImplicitObjectArgument();
      for (int depth = 0; object != nullptr && depth < 64; ++depth) {
        object = object->IgnoreParenImpCasts();
        const CXXRecordDecl* added = nullptr;
        auto consider = [&](const Expr* argument) {
          if (const auto* found = node_class_of_argument(argument)) added = found;
        };
        const Expr* next = nullptr;
        if (const auto* inner = dyn_cast<CallExpr>(object)) {
          for (const Expr* argument : inner->arguments()) consider(argument);
          if (const auto* member_call = dyn_cast<CXXMemberCallExpr>(inner))
            next = member_call->getImplicitObjectArgument();
        } else {
          if (const auto* construct = dyn_cast<CXXConstructExpr>(object))
            for (const Expr* argument : construct->arguments()) consider(argument);
          next = converted_from(object);
        }
        if (added != nullptr) {
          nodes[qualified(added)].realtime_reason = name;
          break;
        }
        object = next;
      }
    }
    return true;
  }

  // The POD messages horus-gen made: explicit TypeInfo<T> specialisations with is_pod = true.
  bool VisitClassTemplateSpecializationDecl(ClassTemplateSpecializationDecl* info) {
    if (!is_horus_class(info, "TypeInfo") || !info->isThisDeclarationADefinition() ||
        info->getTemplateArgs().size() == 0)
      return true;
    const RecordDecl* message = info->getTemplateArgs()[0].getAsType()->getAsRecordDecl();
    // The runtime's own wire types (horus::ServiceRegistration, the frames in horus::detail)
    // come with every service handle and never leave the machine, whose runtime lays them out:
    // no schema of the user's to fix. Generated types live in their package's namespace.
    if (message == nullptr || message->getDefinition() == nullptr || is_runtime_type(message))
      return true;
    bool pod = false;
    std::string schema = qualified(message);
    for (const Decl* decl : info->decls()) {
      const auto* var = dyn_cast<VarDecl>(decl);
      if (var == nullptr || var->getInit() == nullptr) continue;
      if (var->getName() == "is_pod") {
        bool value = false;
        pod = var->getInit()->EvaluateAsBooleanCondition(value, context_) && value;
      } else if (var->getName() == "name") {
        if (auto text = constant_string(var->getInit())) schema = *text;
      }
    }
    if (pod) pods.emplace_back(message->getDefinition(), schema);
    return true;
  }

  std::vector<std::pair<const RecordDecl*, std::string>> pods;

  void lint_ticks() {
    for (const auto& [record, tick] : ticks_) {
      NodeFacts& node = nodes[qualified(record)];
      TickLinter(sources_, node, record->getNameAsString()).lint(tick);
    }
  }

  bool VisitFunctionDecl(FunctionDecl* function) {
    const auto* method = dyn_cast<CXXMethodDecl>(function);
    if (method == nullptr || method->getNameAsString() != "tick" || !method->hasBody() ||
        !method->isThisDeclarationADefinition() || method->getNumParams() != 0 ||
        !derives_from_node(method->getParent()) || method->getParent()->isDependentContext())
      return true;
    ticks_.emplace_back(method->getParent(), method);
    return true;
  }

 private:
  void opened_with(OpenedTopic& opened, const Expr* init) {
    const Expr* stripped = init->IgnoreImplicit();
    if (const auto* list = dyn_cast<ParenListExpr>(stripped); list && list->getNumExprs() > 0)
      stripped = list->getExpr(0);
    if (const auto* construct = dyn_cast<CXXConstructExpr>(stripped);
        construct && construct->getNumArgs() > 0) {
      opened.name = constant_string(construct->getArg(0));
      opened.where = location_of(sources_, construct->getArg(0)->getBeginLoc());
    }
  }

  void note_config(const CXXRecordDecl* record, const Stmt* body) {
    struct Finder : RecursiveASTVisitor<Finder> {
      std::string reason;
      bool VisitMemberExpr(MemberExpr* member) {
        const auto* field = dyn_cast<FieldDecl>(member->getMemberDecl());
        if (field != nullptr &&
            is_horus_class(dyn_cast<CXXRecordDecl>(field->getParent()), "NodeConfig")) {
          const std::string name = field->getNameAsString();
          if (name == "rate" || name == "budget" || name == "deadline") reason = name;
        }
        return reason.empty();
      }
    } finder;
    finder.TraverseStmt(const_cast<Stmt*>(body));
    if (!finder.reason.empty()) nodes[qualified(record)].realtime_reason = finder.reason;
  }

  ASTContext& context_;
  const SourceManager& sources_;
  std::vector<std::pair<const CXXRecordDecl*, const CXXMethodDecl*>> ticks_;
};

class CheckConsumer : public ASTConsumer {
 public:
  void HandleTranslationUnit(ASTContext& context) override {
    if (context.getDiagnostics().hasErrorOccurred()) return;
    FactCollector collector(context);
    collector.TraverseDecl(context.getTranslationUnitDecl());
    collector.lint_ticks();
    check_layouts(context, collector.pods);
  }
};

class CheckAction : public ASTFrontendAction {
 protected:
  std::unique_ptr<ASTConsumer> CreateASTConsumer(CompilerInstance&, llvm::StringRef) override {
    return std::make_unique<CheckConsumer>();
  }
};

// The topics a node's class and its node bases hold, by member.
void gather(const std::string& name, std::map<std::string, OpenedTopic>& topics,
            std::map<std::string, Location>& sent, std::map<std::string, Location>& received,
            std::set<std::string>& seen) {
  if (!seen.insert(name).second) return;
  const NodeFacts& node = nodes[name];
  topics.insert(node.topics.begin(), node.topics.end());
  sent.insert(node.sent.begin(), node.sent.end());
  received.insert(node.received.begin(), node.received.end());
  for (const auto& base : node.bases) gather(base, topics, sent, received, seen);
}

// The nearest class (this one, then its bases) that overrides publishers() / subscribers().
const NodeFacts* declaring(const std::string& name, bool publishers) {
  const NodeFacts& node = nodes[name];
  if (publishers ? node.overrides_publishers : node.overrides_subscribers) return &node;
  for (const auto& base : node.bases)
    if (const NodeFacts* found = declaring(base, publishers)) return found;
  return nullptr;
}

std::string realtime_reason(const std::string& name) {
  const NodeFacts& node = nodes[name];
  if (!node.realtime_reason.empty()) return node.realtime_reason;
  for (const auto& base : node.bases)
    if (auto reason = realtime_reason(base); !reason.empty()) return reason;
  return "";
}

void judge_nodes() {
  std::set<std::string> bases;
  for (const auto& [name, node] : nodes) bases.insert(node.bases.begin(), node.bases.end());
  for (auto& [name, node] : nodes) {
    if (!lint_all_nodes && realtime_reason(name).empty()) continue;
    findings.insert(node.tick_findings.begin(), node.tick_findings.end());
  }
  for (const auto& [name, facts] : nodes) {
    if (bases.count(name) != 0) continue;  // judged through the classes derived from it
    std::map<std::string, OpenedTopic> topics;
    std::map<std::string, Location> sent, received;
    std::set<std::string> seen;
    gather(name, topics, sent, received, seen);
    const NodeFacts* pub_owner = declaring(name, true);
    const NodeFacts* sub_owner = declaring(name, false);
    if ((pub_owner != nullptr && !pub_owner->publishers) ||
        (sub_owner != nullptr && !sub_owner->subscribers))
      continue;  // a declaration whose body no translation unit showed: nothing to compare
    const std::vector<DeclaredTopic> none;
    const auto& pubs = pub_owner != nullptr ? *pub_owner->publishers : none;
    const auto& subs = sub_owner != nullptr ? *sub_owner->subscribers : none;
    auto find = [](const std::vector<DeclaredTopic>& list, const std::string& topic) {
      return std::find_if(list.begin(), list.end(), [&](const auto& d) { return d.name == topic; });
    };
    const std::string short_name =
        name.substr(name.rfind("::") == std::string::npos ? 0 : name.rfind("::") + 2);
    std::set<std::string> opened_names;
    for (const auto& [member, topic] : topics) {
      if (!topic.name) continue;
      opened_names.insert(*topic.name);
      const auto pub = find(pubs, *topic.name);
      const auto sub = find(subs, *topic.name);
      if (pub == pubs.end() && sub == subs.end()) {
        findings.insert({topic.where,
                         "horus-node-undeclared-topic",
                         "node '" + short_name + "' opens topic \"" + *topic.name + "\" (member " +
                             member + ") that its publishers()/subscribers() do not declare",
                         short_name,
                         {}});
        continue;
      }
      const std::string quoted = "topic \"" + *topic.name + "\"";
      auto report = [&](const Location& where, const char* check, const std::string& what) {
        findings.insert({where, check, "node '" + short_name + "' " + what, short_name, {}});
      };
      const DeclaredTopic* declared = pub != pubs.end() ? &*pub : &*sub;
      if (!declared->type.empty() && declared->type != topic.type)
        report(topic.where, "horus-node-topic-type",
               "opens " + quoted + " as " + topic.type + " but declares it as " + declared->type);
      if (auto use = sent.find(member); use != sent.end() && pub == pubs.end())
        report(use->second, "horus-node-direction",
               "sends on " + quoted + " but declares it only in subscribers()");
      if (auto use = received.find(member); use != received.end() && sub == subs.end())
        report(use->second, "horus-node-direction",
               "receives from " + quoted + " but declares it only in publishers()");
    }
    for (const auto* list : {&pubs, &subs}) {
      for (const DeclaredTopic& declared : *list) {
        if (opened_names.count(declared.name) != 0) continue;
        findings.insert({declared.where,
                         "horus-node-unopened-topic",
                         "node '" + short_name + "' declares topic \"" + declared.name + "\" in " +
                             (list == &pubs ? "publishers()" : "subscribers()") +
                             " but opens no topic with that name",
                         short_name,
                         {}});
      }
    }
  }
}

llvm::json::Value location_json(const Location& where) {
  return llvm::json::Object{{"file", where.file}, {"line", where.line}, {"column", where.column}};
}

void print_json() {
  llvm::json::Array finding_list;
  for (const Finding& finding : findings) {
    llvm::json::Object item{{"file", finding.where.file},     {"line", finding.where.line},
                            {"column", finding.where.column}, {"severity", "warning"},
                            {"check", finding.check},         {"message", finding.message}};
    if (!finding.node.empty()) item["node"] = finding.node;
    if (!finding.chain.empty()) item["chain"] = llvm::json::Array(finding.chain);
    finding_list.push_back(std::move(item));
  }
  llvm::json::Array node_list;
  for (const auto& [name, node] : nodes) {
    auto topics = [](const std::map<std::string, OpenedTopic>& members) {
      llvm::json::Array list;
      for (const auto& [member, topic] : members)
        list.push_back(
            llvm::json::Object{{"member", member},
                               {"name", topic.name ? llvm::json::Value(*topic.name) : nullptr},
                               {"type", topic.type}});
      return list;
    };
    auto declared = [](const std::optional<std::vector<DeclaredTopic>>& list) -> llvm::json::Value {
      if (!list) return nullptr;
      llvm::json::Array out;
      for (const auto& topic : *list)
        out.push_back(llvm::json::Object{{"name", topic.name}, {"type", topic.type}});
      return out;
    };
    node_list.push_back(llvm::json::Object{{"name", name},
                                           {"location", location_json(node.where)},
                                           {"bases", llvm::json::Array(node.bases)},
                                           {"realtime", realtime_reason(name)},
                                           {"topics", topics(node.topics)},
                                           {"services", topics(node.services)},
                                           {"publishers", declared(node.publishers)},
                                           {"subscribers", declared(node.subscribers)}});
  }
  llvm::outs() << llvm::formatv("{0:2}", llvm::json::Value(llvm::json::Object{
                                             {"findings", std::move(finding_list)},
                                             {"nodes", std::move(node_list)}}))
               << "\n";
}

void print_text() {
  for (const Finding& finding : findings)
    llvm::outs() << finding.where.file << ":" << finding.where.line << ":" << finding.where.column
                 << ": warning: " << finding.message << " [" << finding.check << "]\n";
}

}  // namespace

int main(int argc, const char** argv) {
  auto parser = tooling::CommonOptionsParser::create(
      argc, argv, check_category, llvm::cl::OneOrMore,
      "horus-check: checks HORUS nodes and generated message layouts in a compile_commands.json\n");
  if (!parser) {
    llvm::errs() << llvm::toString(parser.takeError()) << "\n";
    return 2;
  }
  tooling::ClangTool tool(parser->getCompilations(), parser->getSourcePathList());
  // The database may come from g++: keep its errors, drop its warnings and -Werror, find Clang's
  // own headers (stddef.h, ...) wherever this binary was installed.
  tool.appendArgumentsAdjuster(tooling::getClangStripOutputAdjuster());
  tool.appendArgumentsAdjuster([](const tooling::CommandLineArguments& arguments, llvm::StringRef) {
    tooling::CommandLineArguments adjusted;
    for (const auto& argument : arguments)
      if (llvm::StringRef(argument).startswith("-Werror") == false) adjusted.push_back(argument);
    return adjusted;
  });
  tool.appendArgumentsAdjuster(tooling::getInsertArgumentAdjuster(
      {"-w", "-resource-dir=" HORUS_CHECK_RESOURCE_DIR}, tooling::ArgumentInsertPosition::END));
  if (tool.run(tooling::newFrontendActionFactory<CheckAction>().get()) != 0) {
    llvm::errs() << "horus-check: a translation unit did not compile; no verdict\n";
    return 2;
  }
  judge_nodes();
  if (json_output) {
    print_json();
  } else {
    print_text();
  }
  return findings.empty() ? 0 : 1;
}
