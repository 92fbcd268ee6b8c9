"""A launch file read into a Plan: every process fully expanded (command line, folder, environment,
namespace, parameter file, dependencies, restart policy) in the order it starts.

The file is YAML (docs/launch.md). It is read as PyYAML nodes, which keep the line of every key
and value, so each problem names FILE:LINE and the key it is about; every problem of every file
is collected before LaunchFileError is raised, so a user fixes them in one round.
"""
from __future__ import annotations

import difflib
import os
import re
import shlex
import shutil
import sys
from dataclasses import dataclass

import yaml

RESTART_POLICIES = ("never", "on-failure", "always")
DEFAULT_DEPENDENCY_TIMEOUT = 10.0
DEFAULT_STOP_TIMEOUT = 5.0
INHERITED = "(the launcher's)"

# Process and namespace names become file and folder names (logs, shared memory): the runtime's
# rule for segment names.
SEGMENT_NAME = re.compile(r"[A-Za-z0-9_.-]{1,200}")
ARGUMENT_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
ENVIRONMENT_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
SUBSTITUTION = re.compile(r"\$\(([^()]*)\)")

TOP_KEYS = ("name", "args", "include", "processes", "log_dir")
ARG_KEYS = ("default", "doc", "choices")
INCLUDE_KEYS = ("file", "args", "namespace")
PROCESS_KEYS = ("command", "args", "cwd", "env", "namespace", "params", "depends_on", "restart",
                "backoff", "required", "stop_timeout")
DEPENDENCY_KINDS = ("process", "topic", "service")
BACKOFF_KEYS = ("initial", "max", "limit")


@dataclass(frozen=True)
class Dependency:
    kind: str            # "process" | "topic" | "service"
    name: str
    timeout: float       # seconds; the launch fails with the reason when it passes
    where: str           # "FILE:LINE" of the entry, for messages


@dataclass(frozen=True)
class Backoff:
    initial: float = 0.5  # first delay before a restart, s
    maximum: float = 10.0
    limit: int = 5        # restarts before giving up (0: none)


@dataclass(frozen=True)
class ProcessSpec:
    name: str                     # unique in the whole launch (includes too)
    argv: tuple[str, ...]         # fully expanded; argv[0] the program's absolute path (a
                                  # `horus VERB` runs horus_command(), a *.py this interpreter)
    cwd: str                      # absolute
    env: dict[str, str]           # only what is added to or replaced in the launcher's
                                  # environment, HORUS_NAMESPACE and HORUS_PARAMS_FILE included
    namespace: str                # "" = the launcher's
    params: str | None            # absolute path of the parameter file
    depends_on: tuple[Dependency, ...]
    restart: str                  # one of RESTART_POLICIES
    backoff: Backoff
    required: bool                # its end (after restarts are given up) stops the launch
    stop_timeout: float           # s between SIGINT and SIGKILL at shutdown
    where: str                    # "FILE:LINE" of the process entry


@dataclass(frozen=True)
class Plan:
    name: str                     # the top file's `name:`, else its file name without .yaml
    source: str                   # absolute path of the top file
    processes: tuple[ProcessSpec, ...]   # in start order: dependencies first, then file order
    log_dir: str                  # absolute, from the file's `log_dir:`; "" lets the runner choose
    args: dict[str, str]          # the top file's arguments as resolved (given, else default)


class LaunchFileError(Exception):
    """Every problem found in a launch file and the files it includes, one a line, each
    "FILE:LINE: KEY: what is wrong (hint)"."""

    def __init__(self, errors: list[str]) -> None:
        super().__init__("\n".join(errors))
        self.errors = errors


def parse_arguments(words: list[str]) -> dict[str, str]:
    """The `NAME:=VALUE` words of a command line as a mapping; ValueError names a word that is
    not one."""
    arguments: dict[str, str] = {}
    for word in words:
        name, separator, value = word.partition(":=")
        if not separator or not ARGUMENT_NAME.fullmatch(name):
            raise ValueError(f"'{word}' is not an argument: write NAME:=VALUE (e.g. sim:=true)")
        arguments[name] = value
    return arguments


def load_plan(path: str, arguments: dict[str, str]) -> Plan:
    """The Plan of the launch file at `path` with these command-line arguments; LaunchFileError
    lists every problem found."""
    source = os.path.abspath(path)
    loader = _Loader()
    top = loader.load_file(source, arguments, include_node=None, include_file=None, namespace="",
                           stack=())
    loader.check_dependencies()
    if loader.errors:
        raise LaunchFileError(_in_file_order(loader.errors))
    assert top is not None
    name = top.name or os.path.splitext(os.path.basename(source))[0]
    return Plan(name=name, source=source, processes=tuple(loader.start_order()),
                log_dir=top.log_dir, args=dict(top.arguments))


def horus_command() -> tuple[str, ...]:
    """How a child runs the `horus` command this launcher is: its own script when started as
    `horus`, else the one on PATH, else this interpreter with the package."""
    script = sys.argv[0] if sys.argv else ""
    if os.path.basename(script) == "horus" and os.access(script, os.X_OK):
        return (os.path.abspath(script),)
    found = shutil.which("horus")
    if found:
        return (found,)
    return (sys.executable, "-m", "horus_cli")


def format_plan(plan: Plan) -> str:
    """The plan as `horus launch --dry-run` prints it: each process with everything it gets, in
    start order; the same plan always gives the same text."""
    lines = [f"launch {plan.name}", f"  file: {plan.source}",
             f"  log folder: {plan.log_dir or '(chosen at start)'}"]
    if plan.args:
        lines.append("  arguments:")
        lines += [f"    {name}:={value}" for name, value in sorted(plan.args.items())]
    lines.append(f"  processes, in start order: {len(plan.processes)}")
    for number, process in enumerate(plan.processes, 1):
        lines.append("")
        lines.append(f"{number}. {process.name}  ({process.where})")
        lines.append(f"   command:    {shlex.join(process.argv)}")
        lines.append(f"   cwd:        {process.cwd}")
        lines.append(f"   namespace:  {process.namespace or INHERITED}")
        lines.append(f"   params:     {process.params or '(none)'}")
        if process.env:
            entries = [f"{key}={shlex.quote(value)}" for key, value in sorted(process.env.items())]
            lines.append(f"   env:        {entries[0]}")
            lines += [f"               {entry}" for entry in entries[1:]]
        else:
            lines.append("   env:        (the launcher's, nothing added)")
        if process.depends_on:
            waits = [f"{each.kind} {each.name} (timeout {_seconds(each.timeout)})"
                     for each in process.depends_on]
            lines.append(f"   depends on: {waits[0]}")
            lines += [f"               {wait}" for wait in waits[1:]]
        lines.append(f"   restart:    {_restart_text(process)}")
        required = "yes: its end stops the launch" if process.required else "no"
        lines.append(f"   required:   {required}")
        lines.append(f"   stop:       SIGINT, then SIGKILL after {_seconds(process.stop_timeout)}")
    return "\n".join(lines) + "\n"


def _seconds(value: float) -> str:
    return f"{value:g} s"


def _restart_text(process: ProcessSpec) -> str:
    if process.restart == "never":
        return "never"
    backoff = process.backoff
    return (f"{process.restart}, after {_seconds(backoff.initial)} doubling up to "
            f"{_seconds(backoff.maximum)}, at most {backoff.limit} times")


def display_path(path: str) -> str:
    """A file as messages name it: relative to the current folder when under it."""
    relative = os.path.relpath(path)
    return relative if not relative.startswith("..") else path


def _suggestion(word: str, choices) -> str:
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f"did you mean '{close[0]}'?" if close else ""


def _hint(*parts: str) -> str:
    text = ""
    for part in filter(None, parts):
        text += ("" if not text else " " if text.endswith("?") else "; ") + part
    return f" ({text})" if text else ""


@dataclass
class _FileResult:
    name: str
    log_dir: str
    arguments: dict[str, str]


class _File:
    """One launch file being read: where its messages point, its folder, its arguments."""

    def __init__(self, loader: _Loader, path: str) -> None:
        self.loader = loader
        self.path = path
        self.shown = display_path(path)
        self.folder = os.path.dirname(path)
        self.arguments: dict[str, str] = {}
        self.declared: list[str] = []  # every argument declared, given a value or not

    def where(self, node) -> str:
        return f"{self.shown}:{node.start_mark.line + 1}"

    def error(self, node, key: str, what: str, *hints: str) -> None:
        self.loader.errors.append(f"{self.where(node)}: {key}: {what}{_hint(*hints)}")

    # -- shapes -------------------------------------------------------------------------------

    def mapping(self, node, key: str, allowed) -> dict | None:
        """A mapping's entries by key, each (key node, value node); unknown and repeated keys are
        reported. None (reported) when the node is not a mapping."""
        if node is None or _is_null(node):
            return {}
        if not isinstance(node, yaml.MappingNode):
            self.error(node, key or "launch file",
                       f"expected a mapping of {', '.join(allowed)}, got {_shape(node)}")
            return None
        entries: dict = {}
        for key_node, value_node in node.value:
            name = key_node.value if isinstance(key_node, yaml.ScalarNode) else None
            here = f"{key}.{name}" if key else str(name)
            if name not in allowed:
                self.error(key_node, here, "unknown key",
                           _suggestion(str(name), allowed),
                           f"known: {', '.join(allowed)}")
                continue
            if name in entries:
                self.error(key_node, here, f"given twice (first at line "
                                           f"{entries[name][0].start_mark.line + 1})")
                continue
            entries[name] = (key_node, value_node)
        return entries

    def pairs(self, node, key: str) -> list | None:
        """A mapping whose keys are names (processes, args, env): its (key node, value node)
        pairs in file order; None (reported) when the node is not a mapping."""
        if node is None or _is_null(node):
            return []
        if not isinstance(node, yaml.MappingNode):
            self.error(node, key, f"expected a mapping of names, got {_shape(node)}",
                       f"write each as NAME: VALUE under {key.rsplit('.', 1)[-1]}:")
            return None
        return list(node.value)

    def sequence(self, node, key: str) -> list | None:
        """A list's items; a single item stands for a list of one. None when null."""
        if node is None or _is_null(node):
            return []
        if isinstance(node, yaml.SequenceNode):
            return list(node.value)
        return [node]

    # -- values -------------------------------------------------------------------------------

    def text(self, node, key: str, allow_empty: bool = False) -> str | None:
        """A scalar as text, its substitutions expanded (numbers and booleans as written)."""
        if not isinstance(node, yaml.ScalarNode) or _is_null(node):
            self.error(node, key, f"expected a text, got {_shape(node)}")
            return None
        value = self.expand(node.value, node, key)
        if value is not None and not value and not allow_empty:
            self.error(node, key, "must not be empty")
            return None
        return value

    def words(self, node, key: str) -> list[str] | None:
        """A scalar split into words as a shell would, then each expanded: a substitution's value
        stays one word, spaces and all."""
        if not isinstance(node, yaml.ScalarNode) or _is_null(node):
            self.error(node, key, f"expected a text, got {_shape(node)}")
            return None
        found: list[str] = []

        def set_aside(match: re.Match) -> str:
            found.append(match.group(0))
            return f"\x00{len(found) - 1}\x00"

        try:
            raw_words = shlex.split(SUBSTITUTION.sub(set_aside, node.value))
        except ValueError as error:
            self.error(node, key, f"cannot split into words ({error})",
                       "quote a word with spaces, or give it under args:")
            return None
        if not raw_words:
            self.error(node, key, "must not be empty")
            return None
        words = [self.expand(re.sub("\x00(\\d+)\x00", lambda match: found[int(match.group(1))],
                                    word), node, key) for word in raw_words]
        return None if None in words else words

    def number(self, node, key: str, minimum: float, above: bool) -> float | None:
        text = self.text(node, key)
        if text is None:
            return None
        try:
            value = float(text)
        except ValueError:
            self.error(node, key, f"expected a number of seconds, got '{text}'")
            return None
        if value != value or value in (float("inf"), float("-inf")) or value < minimum or (
                above and value == minimum):
            bound = f"above {minimum:g}" if above else f"at least {minimum:g}"
            self.error(node, key, f"expected a number of seconds {bound}, got '{text}'")
            return None
        return value

    def integer(self, node, key: str) -> int | None:
        text = self.text(node, key)
        if text is None:
            return None
        if not re.fullmatch(r"\d+", text):
            self.error(node, key, f"expected a whole number of at least 0, got '{text}'")
            return None
        return int(text)

    def boolean(self, node, key: str) -> bool | None:
        text = self.text(node, key)
        if text is None:
            return None
        lowered = text.lower()
        if lowered in ("true", "yes", "on"):
            return True
        if lowered in ("false", "no", "off"):
            return False
        self.error(node, key, f"expected true or false, got '{text}'")
        return None

    def segment_name(self, node, key: str, what: str) -> str | None:
        text = self.text(node, key)
        if text is not None and (not SEGMENT_NAME.fullmatch(text) or text in (".", "..")):
            self.error(node, key, f"{what} '{text}' is not valid",
                       "use 1 to 200 of A-Z a-z 0-9 _ . - (and not . or ..)")
            return None
        return text

    def existing_path(self, node, key: str, what: str) -> str | None:
        """A path relative to this file's folder, made absolute; it must exist."""
        text = self.text(node, key)
        if text is None:
            return None
        resolved = os.path.normpath(os.path.join(self.folder, os.path.expanduser(text)))
        if not os.path.exists(resolved):
            self.error(node, key, f"no {what} '{text}'",
                       f"looked for {resolved}; a relative path starts at the launch file's "
                       "folder")
            return None
        return resolved

    # -- substitutions ------------------------------------------------------------------------

    def expand(self, text: str, node, key: str) -> str | None:
        """`text` with each $(env NAME), $(env NAME default), $(arg NAME) and $(dir) replaced;
        None (reported) when one cannot be."""
        problems = 0

        def replace(match: re.Match) -> str:
            nonlocal problems
            words = match.group(1).split(None, 2)
            verb = words[0] if words else ""
            if verb == "env" and len(words) >= 2:
                default = words[2] if len(words) == 3 else None
                if default and len(default) >= 2 and default[0] == default[-1] in "'\"":
                    default = default[1:-1]  # quoted: '' for empty, or spaces kept at the ends
                value = os.environ.get(words[1], default)
                if value is None:
                    problems += 1
                    self.error(node, key, f"$(env {words[1]}): the environment variable is not "
                                          "set", f"give a default: $(env {words[1]} VALUE)")
                    return ""
                return value
            if verb == "arg" and len(words) == 2:
                if words[1] in self.arguments:
                    return self.arguments[words[1]]
                problems += 1
                if words[1] not in self.declared:  # a declared one without value is reported
                    declared = ", ".join(self.declared) or "none"
                    self.error(node, key, f"$(arg {words[1]}): no such argument in this file",
                               _suggestion(words[1], self.declared),
                               f"declared under args: {declared}")
                return ""
            if verb == "dir" and len(words) == 1:
                return self.folder
            problems += 1
            self.error(node, key, f"'{match.group(0)}' is not a substitution",
                       _suggestion(verb, ("env", "arg", "dir")),
                       "known: $(env NAME), $(env NAME default), $(arg NAME), $(dir)")
            return ""

        value = SUBSTITUTION.sub(replace, text)
        if problems == 0 and "$(" in value and "$(" in text:
            self.error(node, key, "'$(' without its closing ')'",
                       "write $(env NAME), $(arg NAME) or $(dir)")
            return None
        return None if problems else value


class _Loader:
    """Reads the top file and its includes into processes, collecting every problem."""

    def __init__(self) -> None:
        self.errors: list[str] = []
        self.processes: dict[str, ProcessSpec] = {}  # read without a problem, in file order
        # Every process read, with a problem or not, by name: where it is, its key and the
        # dependencies that read (so a broken entry's neighbours get no false "no process").
        self.defined: dict[str, str] = {}
        self.graph: dict[str, list] = {}
        self._verbs: tuple[str, ...] | None = None

    # -- files --------------------------------------------------------------------------------

    def load_file(self, path: str, given: dict[str, str], include_node, include_file,
                  namespace: str, stack: tuple[str, ...],
                  include_key: str = "include") -> _FileResult | None:
        file = _File(self, path)
        try:
            with open(path, encoding="utf-8") as stream:
                root = yaml.compose(stream, Loader=yaml.SafeLoader)
        except OSError as error:
            reason = error.strerror or str(error)
            if include_file is None:
                self.errors.append(f"{file.shown}:1: launch file: cannot read it ({reason})")
            else:
                include_file.error(include_node, f"{include_key}.file",
                                   f"cannot read '{file.shown}' ({reason})")
            return None
        except yaml.YAMLError as error:
            mark = getattr(error, "problem_mark", None)
            line = mark.line + 1 if mark is not None else 1
            problem = getattr(error, "problem", None) or str(error)
            self.errors.append(f"{file.shown}:{line}: YAML: {problem} (the file is not valid "
                               "YAML: check the indentation and quote values with ': ' or '#')")
            return None
        if root is None:
            self.errors.append(f"{file.shown}:1: launch file: empty (give processes:)")
            return None
        top = file.mapping(root, "", TOP_KEYS)
        if top is None:
            return None
        result = _FileResult(name="", log_dir="", arguments={})
        result.arguments = self.read_arguments(file, top.get("args"), given, include_node,
                                               include_file, include_key)
        for key in ("name", "log_dir"):
            if key not in top:
                continue
            key_node, value_node = top[key]
            if include_file is not None:
                file.error(key_node, key, "only the top launch file sets it",
                           f"this file is included from {include_file.where(include_node)}")
                continue
            if key == "name":
                result.name = file.segment_name(value_node, key, "launch name") or ""
            else:
                text = file.text(value_node, key)
                if text:
                    result.log_dir = os.path.normpath(os.path.join(
                        file.folder, os.path.expanduser(text)))
        if "include" in top:
            self.read_includes(file, top["include"][1], namespace, stack + (path,))
        if "processes" in top:
            self.read_processes(file, top["processes"][1], namespace)
        elif include_file is None and not self.defined:
            file.error(root, "processes", "the launch starts no process",
                       "list them under processes:")
        return result

    def read_arguments(self, file: _File, node, given: dict[str, str], include_node,
                       include_file, include_key: str) -> dict[str, str]:
        """The file's declared arguments: the value given (command line or include), else the
        default; a given one the file does not declare, and one with neither, are reported."""
        values: dict[str, str] = {}
        file.arguments = values  # defaults may use the arguments declared before them
        pairs = file.pairs(node[1], "args") if node is not None else []
        for key_node, value_node in pairs or []:
            name = key_node.value if isinstance(key_node, yaml.ScalarNode) else ""
            key = f"args.{name}"
            if not ARGUMENT_NAME.fullmatch(str(name)):
                file.error(key_node, key, f"'{name}' is not an argument name",
                           "use letters, digits and _, not starting with a digit")
                continue
            if name in file.declared:
                file.error(key_node, key, "declared twice")
                continue
            default_node = value_node
            choices: list[str] | None = None
            if isinstance(value_node, yaml.MappingNode):
                entries = file.mapping(value_node, key, ARG_KEYS) or {}
                default_node = entries.get("default", (None, None))[1]
                doc = entries.get("doc", (None, None))[1]
                if doc is not None and not isinstance(doc, yaml.ScalarNode):
                    file.error(doc, f"{key}.doc", f"expected a text, got {_shape(doc)}")
                if "choices" in entries:
                    choices = self.read_choices(file, entries["choices"][1], f"{key}.choices")
            file.declared.append(name)
            if name in given:
                values[name] = given[name]
            elif default_node is not None and not _is_null(default_node):
                default = file.text(default_node, f"{key}.default", allow_empty=True)
                if default is not None:
                    values[name] = default
            else:
                if include_file is None:
                    file.error(key_node, key, "has no default and was not given",
                               f"give it on the command line: {name}:=VALUE")
                else:
                    include_file.error(include_node, f"{include_key}.args",
                                       f"{file.shown} needs argument '{name}', which has "
                                       "no default", f"add it: args: {{{name}: VALUE}}")
            if choices and name in values and values[name] not in choices:
                origin = ("given on the command line" if include_file is None else
                          f"given at {include_file.where(include_node)}") if name in given else (
                    "its default")
                file.error(key_node, key, f"'{values[name]}' ({origin}) is not one of "
                                          f"{', '.join(choices)}",
                           _suggestion(values[name], choices))
                del values[name]
        for name, value in given.items():
            if name in file.declared:
                continue
            choices = ", ".join(file.declared) or "none"
            if include_file is None:
                where = node[0] if node is not None else None
                self.errors.append(
                    f"{file.where(where) if where is not None else file.shown + ':1'}: args: "
                    f"{name}:={value} was given but the file declares no argument '{name}'"
                    f"{_hint(_suggestion(name, file.declared), f'declared: {choices}')}")
            else:
                include_file.error(include_node, f"{include_key}.args.{name}",
                                   f"{file.shown} declares no argument '{name}'",
                                   _suggestion(name, file.declared), f"declared: {choices}")
        return values

    def read_choices(self, file: _File, node, key: str) -> list[str] | None:
        """The values an argument may take, as texts (no substitutions: they are the rule)."""
        items = file.sequence(node, key) or []
        if not items or not all(isinstance(item, yaml.ScalarNode) and not _is_null(item)
                                for item in items):
            file.error(node, key, "expected a list of values", "e.g. choices: [true, false]")
            return None
        return [item.value for item in items]

    def read_includes(self, file: _File, node, namespace: str, stack: tuple[str, ...]) -> None:
        for index, item in enumerate(file.sequence(node, "include") or []):
            key = f"include[{index}]"
            if isinstance(item, yaml.ScalarNode):
                entries = {"file": (item, item)}
            else:
                entries = file.mapping(item, key, INCLUDE_KEYS)
                if entries is None:
                    continue
            if "file" not in entries:
                file.error(item, key, "names no file", "give file: OTHER.yaml")
                continue
            target = file.existing_path(entries["file"][1], f"{key}.file", "file")
            given: dict[str, str] = {}
            for key_node, value_node in (file.pairs(entries["args"][1], f"{key}.args")
                                         if "args" in entries else []) or []:
                value = file.text(value_node, f"{key}.args.{key_node.value}", allow_empty=True)
                if value is not None:
                    given[str(key_node.value)] = value
            inner = namespace
            if "namespace" in entries:
                inner = file.segment_name(entries["namespace"][1], f"{key}.namespace",
                                          "namespace") or namespace
            if target is None:
                continue
            if target in stack:
                chain = " -> ".join(display_path(each) for each in (*stack, target))
                file.error(entries["file"][1], f"{key}.file", f"include cycle: {chain}")
                continue
            self.load_file(target, given, item, file, inner, stack, key)

    # -- processes ----------------------------------------------------------------------------

    def read_processes(self, file: _File, node, namespace: str) -> None:
        for key_node, value_node in file.pairs(node, "processes") or []:
            name = file.segment_name(key_node, "processes", "process name")
            if name is None:
                continue
            key = f"processes.{name}"
            if name in self.defined:
                first = self.defined[name]
                file.error(key_node, key, f"a process named '{name}' is already defined at "
                                          f"{first}", "process names are unique in the whole "
                                                      "launch, included files too")
                # Read all the same, for the problems of its own.
                self.read_process(file, name, key, key_node, value_node, namespace)
                continue
            self.defined[name] = file.where(key_node)
            spec = self.read_process(file, name, key, key_node, value_node, namespace)
            if spec is not None:
                self.processes[name] = spec

    def read_process(self, file: _File, name: str, key: str, key_node, node,
                     namespace: str) -> ProcessSpec | None:
        entries = file.mapping(node, key, PROCESS_KEYS)
        if entries is None:
            return None
        ok = True

        def value(field_name: str, read, *extra):
            nonlocal ok
            if field_name not in entries:
                return None
            result = read(entries[field_name][1], f"{key}.{field_name}", *extra)
            if result is None:
                ok = False
            return result

        env: dict[str, str] = {}
        for env_key, env_value in (value("env", file.pairs) or []):
            env_name = env_key.value if isinstance(env_key, yaml.ScalarNode) else ""
            here = f"{key}.env.{env_name}"
            if not ENVIRONMENT_NAME.fullmatch(str(env_name)):
                file.error(env_key, here, f"'{env_name}' is not an environment variable name")
                ok = False
            elif env_name in ("HORUS_NAMESPACE", "HORUS_PARAMS_FILE"):
                instead = "namespace" if env_name == "HORUS_NAMESPACE" else "params"
                file.error(env_key, here, "set by the launcher", f"use {key}.{instead}")
                ok = False
            else:
                text = file.text(env_value, here, allow_empty=True)
                if text is None:
                    ok = False
                else:
                    env[env_name] = text
        process_namespace = value("namespace", file.segment_name, "namespace") or namespace
        params = value("params", file.existing_path, "parameter file")
        cwd = value("cwd", file.existing_path, "folder") or os.getcwd()
        if "cwd" in entries and cwd and not os.path.isdir(cwd):
            file.error(entries["cwd"][1], f"{key}.cwd", f"'{cwd}' is not a folder")
            ok = False
        argv = None
        if "command" not in entries:
            file.error(key_node, key, "has no command", "give command: PROGRAM")
            ok = False
        else:
            argv = self.read_command(file, entries, key, env)
            ok = ok and argv is not None
        restart = "never"
        if "restart" in entries:
            restart_node = entries["restart"][1]
            restart = file.text(restart_node, f"{key}.restart")
            if restart is not None and restart not in RESTART_POLICIES:
                file.error(restart_node, f"{key}.restart",
                           f"expected never, on-failure or always, got '{restart}'",
                           _suggestion(restart.replace("_", "-"), RESTART_POLICIES))
                restart = None
            ok = ok and restart is not None
        backoff = Backoff()
        if "backoff" in entries:
            backoff = self.read_backoff(file, entries["backoff"][1], f"{key}.backoff")
            ok = ok and backoff is not None
        required = value("required", file.boolean)
        stop_timeout = value("stop_timeout", file.number, 0.0, True)
        dependencies = []
        for index, item in enumerate(file.sequence(entries["depends_on"][1], "")
                                     if "depends_on" in entries else []):
            item_key = f"{key}.depends_on[{index}]"
            dependency = self.read_dependency(file, item, item_key)
            if dependency is None:
                ok = False
            else:
                dependencies.append((dependency, item, file, item_key))
        if self.defined.get(name) == file.where(key_node):  # not a repeated name
            self.graph[name] = dependencies
        if not ok:
            return None
        if process_namespace:
            env["HORUS_NAMESPACE"] = process_namespace
        if params:
            env["HORUS_PARAMS_FILE"] = params
        return ProcessSpec(
            name=name, argv=argv, cwd=cwd, env=env, namespace=process_namespace, params=params,
            depends_on=tuple(each[0] for each in dependencies), restart=restart,
            backoff=backoff, required=bool(required),
            stop_timeout=DEFAULT_STOP_TIMEOUT if stop_timeout is None else stop_timeout,
            where=file.where(key_node))

    def read_command(self, file: _File, entries: dict, key: str,
                     env: dict[str, str]) -> tuple[str, ...] | None:
        """The command line: `command` (a program and maybe its first words) then `args`, with
        the program resolved to the file it runs."""
        command_node = entries["command"][1]
        words = file.words(command_node, f"{key}.command")
        if words is None:
            return None
        arguments = []
        ok = True
        if "args" in entries:
            args_node = entries["args"][1]
            if isinstance(args_node, yaml.ScalarNode) and not _is_null(args_node):
                file.error(args_node, f"{key}.args", "expected a list of arguments, got a text",
                           "write args: [--rate, '10'] (one item per argument)")
                return None
            for index, item in enumerate(file.sequence(args_node, f"{key}.args") or []):
                word = file.text(item, f"{key}.args[{index}]", allow_empty=True)
                if word is None:
                    ok = False
                else:
                    arguments.append(word)
        program = self.resolve_program(file, command_node, f"{key}.command", words, env)
        if program is None or not ok:
            return None
        return (*program, *words[1:], *arguments)

    def resolve_program(self, file: _File, node, key: str, words: list[str],
                        env: dict[str, str]) -> tuple[str, ...] | None:
        program = words[0]
        if program == "horus":
            if len(words) < 2:
                file.error(node, key, "'horus' needs a command", "e.g. horus record ...")
                return None
            verbs = self.horus_verbs()
            if words[1] not in verbs:
                file.error(node, key, f"unknown command 'horus {words[1]}'",
                           _suggestion(words[1], verbs), "`horus --help` lists them")
                return None
            return horus_command()
        if "/" in program or program.endswith(".py"):
            resolved = os.path.normpath(os.path.join(file.folder, os.path.expanduser(program)))
            if not os.path.isfile(resolved):
                file.error(node, key, f"unknown command: no file '{program}'",
                           f"looked for {resolved}; a relative path starts at the launch "
                           "file's folder")
                return None
            if program.endswith(".py"):
                return (sys.executable, resolved)
            if not os.access(resolved, os.X_OK):
                file.error(node, key, f"'{program}' is not executable",
                           f"chmod +x {resolved}, or run it through its interpreter")
                return None
            return (resolved,)
        found = shutil.which(program, path=env.get("PATH", os.environ.get("PATH")))
        if found is None:
            file.error(node, key, f"unknown command: no program '{program}' on PATH",
                       "a file beside the launch file is written ./" + program)
            return None
        return (found,)

    def horus_verbs(self) -> tuple[str, ...]:
        if self._verbs is None:
            from horus_cli.main import build_parser
            parser = build_parser()
            verbs = next(action.choices for action in parser._actions  # noqa: SLF001
                         if getattr(action, "choices", None) and isinstance(action.choices, dict))
            self._verbs = tuple(verbs)
        return self._verbs

    def read_backoff(self, file: _File, node, key: str) -> Backoff | None:
        entries = file.mapping(node, key, BACKOFF_KEYS)
        if entries is None:
            return None
        defaults = Backoff()
        initial = defaults.initial
        maximum = defaults.maximum
        limit = defaults.limit
        ok = True
        if "initial" in entries:
            initial = file.number(entries["initial"][1], f"{key}.initial", 0.0, True)
            ok = ok and initial is not None
        if "max" in entries:
            maximum = file.number(entries["max"][1], f"{key}.max", 0.0, True)
            ok = ok and maximum is not None
        if "limit" in entries:
            limit = file.integer(entries["limit"][1], f"{key}.limit")
            ok = ok and limit is not None
        if not ok:
            return None
        if maximum < initial:
            file.error(entries.get("max", (node, node))[1], f"{key}.max",
                       f"{maximum:g} s is below initial {initial:g} s",
                       "the delay doubles from initial up to max")
            return None
        return Backoff(initial=initial, maximum=maximum, limit=limit)

    def read_dependency(self, file: _File, node, key: str) -> Dependency | None:
        if isinstance(node, yaml.ScalarNode):
            name = file.text(node, key)
            return None if name is None else Dependency(
                "process", name, DEFAULT_DEPENDENCY_TIMEOUT, file.where(node))
        entries = file.mapping(node, key, (*DEPENDENCY_KINDS, "timeout"))
        if entries is None:
            return None
        kinds = [kind for kind in DEPENDENCY_KINDS if kind in entries]
        if len(kinds) != 1:
            file.error(node, key, "names " + ("no" if not kinds else "more than one") +
                       " dependency", "give one of process: NAME, topic: NAME, service: NAME")
            return None
        name = file.text(entries[kinds[0]][1], f"{key}.{kinds[0]}")
        if name is not None and any(character.isspace() for character in name):
            file.error(entries[kinds[0]][1], f"{key}.{kinds[0]}", f"'{name}' is not a name")
            name = None
        timeout = DEFAULT_DEPENDENCY_TIMEOUT
        if "timeout" in entries:
            timeout = file.number(entries["timeout"][1], f"{key}.timeout", 0.0, True)
        if name is None or timeout is None:
            return None
        return Dependency(kinds[0], name, timeout, file.where(node))

    # -- the whole launch ---------------------------------------------------------------------

    def check_dependencies(self) -> None:
        """Every process dependency names a process of the launch, and none is in a cycle."""
        names = list(self.defined)
        for dependencies in self.graph.values():
            for dependency, item, file, key in dependencies:
                if dependency.kind == "process" and dependency.name not in self.defined:
                    file.error(item, key,
                               f"no process named '{dependency.name}' in this launch",
                               _suggestion(dependency.name, names),
                               f"processes: {', '.join(names)}")
        reported: set[frozenset] = set()
        for cycle in self.cycles():
            members = frozenset(cycle)
            if members in reported:
                continue
            reported.add(members)
            _, item, file, key = next(each for each in self.graph[cycle[0]]
                                      if each[0].kind == "process" and each[0].name == cycle[1])
            places = ", ".join(f"{name} at {self.defined[name]}" for name in cycle[:-1])
            file.error(item, key, "dependency cycle: " + " -> ".join(cycle),
                       f"{places}; remove one of these dependencies")

    def process_dependencies(self, name: str) -> list[str]:
        """The processes `name` waits for (those the launch has)."""
        return [each.name for each, *_ in self.graph.get(name, [])
                if each.kind == "process" and each.name in self.graph]

    def cycles(self) -> list[list[str]]:
        """Each dependency cycle as its names, the first repeated at the end."""
        state: dict[str, str] = {}
        found: list[list[str]] = []
        path: list[str] = []

        def visit(name: str) -> None:
            state[name] = "visiting"
            path.append(name)
            for needed in self.process_dependencies(name):
                if state.get(needed) == "visiting":
                    found.append(path[path.index(needed):] + [needed])
                elif needed not in state:
                    visit(needed)
            path.pop()
            state[name] = "done"

        for name in self.graph:
            if name not in state:
                visit(name)
        return found

    def start_order(self) -> list[ProcessSpec]:
        """Dependencies first, otherwise file order (includes where they are read)."""
        placed: list[str] = []
        waiting = list(self.processes)
        while waiting:
            ready = next(name for name in waiting if all(
                needed in placed for needed in self.process_dependencies(name)))
            placed.append(ready)
            waiting.remove(ready)
        return [self.processes[name] for name in placed]


def _in_file_order(errors: list[str]) -> list[str]:
    """The errors by file (in the order the files were read), then line."""
    files: dict[str, int] = {}

    def position(error: str) -> tuple[int, int]:
        file, _, rest = error.partition(":")
        line = rest.partition(":")[0]
        return files.setdefault(file, len(files)), int(line) if line.isdigit() else 0

    for error in errors:
        position(error)
    return sorted(errors, key=position)


def _is_null(node) -> bool:
    return isinstance(node, yaml.ScalarNode) and node.tag == "tag:yaml.org,2002:null"


def _shape(node) -> str:
    if node is None or _is_null(node):
        return "nothing"
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    return f"'{node.value}'"
