"""Recursive-descent parser: tokens -> syntax tree, reporting every syntax error it can recover from.

After an error the parser skips to the next `,` or `}` of the block it is in, so one typo yields
one diagnostic and the rest of the file is still checked.
"""
from __future__ import annotations

from .diagnostics import Note, Reporter, Source, Span, near_miss
from .lexer import Kind, Token, tokenize
from .syntax import (ActionDecl, Attribute, ConstDecl, EnumDecl, EnumVariant, FieldDecl, FileSyntax, Literal,
                     MessageDecl, NodeDecl, NodeEndpointDecl, NodeSettingDecl, ServiceDecl, TypeExpr)

FILE_KINDS = {".hmsg": "message", ".hsrv": "service", ".haction": "action", ".hnode": "node"}
# The blocks of an action, in the order its generated types list them.
ACTION_BLOCKS = ("goal", "result", "feedback")
# The blocks of a node: topics it subscribes to and publishes, services it calls and serves.
NODE_BLOCKS = ("sub", "pub", "client", "server")


# How deep types (arrays, Vec, Option) and list values may nest (docs/schema-language.md, "Limits"):
# numpy arrays have at most 32 dimensions, and every stage of horus-gen walks types recursively.
MAX_NESTING = 16


class _Recover(Exception):
    """Raised after an error has been reported, to resynchronise at the enclosing block."""


class Parser:
    def __init__(self, source: Source, reporter: Reporter, file_kind: str):
        self.source = source
        self.reporter = reporter
        self.file_kind = file_kind
        self.tokens = tokenize(source, reporter)
        self.pos = 0
        self.nesting = 0

    # -- token helpers -------------------------------------------------------------------------
    def peek(self, ahead: int = 0) -> Token:
        return self.tokens[min(self.pos + ahead, len(self.tokens) - 1)]

    def advance(self) -> Token:
        token = self.peek()
        if token.kind is not Kind.EOF:
            self.pos += 1
        return token

    def accept_punct(self, text: str) -> Token | None:
        if self.peek().is_punct(text):
            return self.advance()
        return None

    def fail(self, span: Span, message: str, hint: str | None = None) -> _Recover:
        self.reporter.error(span, message, hint)
        return _Recover()

    def expect_punct(self, text: str, context: str, hint: str | None = None) -> Token:
        token = self.peek()
        if token.is_punct(text):
            return self.advance()
        raise self.fail(token.span, f"expected '{text}' {context}, found {token.describe()}", hint)

    def expect_ident(self, what: str) -> Token:
        token = self.peek()
        if token.kind is Kind.IDENT:
            return self.advance()
        raise self.fail(token.span, f"expected {what}, found {token.describe()}")

    def skip_to_member_end(self) -> None:
        """Skips to just after the next ',' (or to the '}') of the current block."""
        depth = 0
        while True:
            token = self.peek()
            if token.kind is Kind.EOF:
                return
            if token.kind is Kind.PUNCT:
                if token.text in "{[(":
                    depth += 1
                elif token.text in ")]":
                    depth = max(0, depth - 1)
                elif token.text == "}":
                    if depth == 0:
                        return
                    depth -= 1
                elif token.text == "," and depth == 0:
                    self.advance()
                    return
            self.advance()

    def skip_block(self) -> None:
        """Skips the `{ ... }` block of an unknown part (and a ',' after it), so that the parts after
        it are still read; without a block, resynchronises as after any error."""
        open_brace = self.accept_punct("{")
        if open_brace is None:
            raise _Recover()
        self.parse_block(open_brace, "block", self.skip_to_member_end)
        self.accept_punct(",")

    def skip_item(self) -> None:
        """Skips the rest of a top-level item: up to and including its closing '}'."""
        depth = 0
        while True:
            token = self.advance()
            if token.kind is Kind.EOF:
                return
            if token.is_punct("{"):
                depth += 1
            elif token.is_punct("}"):
                depth -= 1
                if depth <= 0:
                    return
            elif token.is_punct(";") and depth == 0:
                return

    # -- file --------------------------------------------------------------------------------
    def parse_file(self) -> FileSyntax:
        syntax = FileSyntax(self.source)
        while self.peek().kind is not Kind.EOF:
            start = self.pos
            try:
                self.parse_top_level(syntax)
            except _Recover:
                self.skip_item()
            if self.pos == start:
                self.advance()
        return syntax

    def parse_top_level(self, syntax: FileSyntax) -> None:
        token = self.peek()
        if token.is_word("package"):
            self.advance()
            path, span = self.parse_dotted_path("a package name such as 'my_robot.msg'")
            self.expect_punct(";", "after the package name")
            if syntax.package is not None:
                self.reporter.error(span, "a file declares its package once")
            elif syntax.items:
                self.reporter.error(span, "'package' must come before the first item")
            else:
                syntax.package = (path, span)
            return
        if token.is_word("import"):
            self.advance()
            target = self.peek()
            if target.kind is not Kind.STRING:
                raise self.fail(target.span, f"expected a quoted path after 'import', found {target.describe()}",
                                'write: import "horus/msg/geometry.hmsg";')
            self.advance()
            self.expect_punct(";", "after the import path")
            syntax.imports.append((str(target.value), target.span))
            return
        if any(token.is_word(w) for w in ("message", "service", "action", "node")) and self.peek(1).is_punct("!"):
            self.parse_macro_block(syntax)
            return
        syntax.items.append(self.parse_item())

    def parse_macro_block(self, syntax: FileSyntax) -> None:
        """`message! { ... }` / `service! { ... }` / `action! { ... }` / `node! { ... }`: the Rust macro
        form, accepted unchanged."""
        self.advance()
        self.advance()
        open_brace = self.expect_punct("{", "after the macro name")
        while not self.peek().is_punct("}"):
            if self.peek().kind is Kind.EOF:
                raise self.fail(open_brace.span, "unterminated macro block: expected '}'")
            start = self.pos
            try:
                syntax.items.append(self.parse_item())
            except _Recover:
                self.skip_item()
            if self.pos == start:
                self.advance()
        self.advance()

    def parse_prefix(self) -> tuple[tuple[Attribute, ...], tuple[str, ...]]:
        attributes: list[Attribute] = []
        docs: list[str] = []
        while True:
            token = self.peek()
            if token.kind is Kind.DOC:
                docs.append(str(token.value))
                self.advance()
            elif token.is_punct("#["):
                attributes.append(self.parse_attribute())
            else:
                return tuple(attributes), tuple(docs)

    def parse_attribute(self) -> Attribute:
        self.advance()
        name = self.expect_ident("an attribute name")
        value = None
        if self.accept_punct("="):
            value = self.parse_literal()
        elif self.peek().is_punct("("):
            value = self.parse_attribute_list(name)
        self.expect_punct("]", f"to close attribute '{name.text}'")
        return Attribute(name.text, value, name.span)

    def parse_attribute_list(self, name: Token) -> Literal:
        """`(Debug, Clone, serde::Serialize)`: the names of a list attribute such as `derive`."""
        open_paren = self.advance()
        names: list[Literal] = []
        while not self.peek().is_punct(")"):
            first = self.expect_ident(f"a name in the list of attribute '{name.text}'")
            path = [first.text]
            while self.accept_punct("::"):
                path.append(self.expect_ident("a name after '::'").text)
            end = self.tokens[self.pos - 1].span
            names.append(Literal("path", tuple(path), Span(first.span.source, first.span.line, first.span.col,
                                                           end.col + end.length - first.span.col)))
            if not self.accept_punct(","):
                break
        self.expect_punct(")", f"to close the list of attribute '{name.text}'")
        return Literal("list", tuple(names), open_paren.span)

    def parse_item(self) -> MessageDecl | EnumDecl | ServiceDecl | ActionDecl | NodeDecl:
        attributes, docs = self.parse_prefix()
        while self.peek().is_word("pub"):
            self.advance()
        if self.file_kind == "node":
            return self.parse_node(attributes, docs)
        if self.peek().is_word("enum"):
            return self.parse_enum(attributes, docs)
        if self.peek().is_word("struct"):
            self.advance()
        name = self.peek()
        if name.kind is not Kind.IDENT:
            expected = {"message": "a message name", "service": "a service name"}.get(self.file_kind, "an action name")
            raise self.fail(name.span, f"expected {expected} or 'enum', found {name.describe()}")
        self.advance()
        open_brace = self.expect_punct("{", f"after '{name.text}'",
                                       f"an item reads: {name.text} {{ ... }}")
        if self.file_kind == "service":
            return self.parse_service_body(name, open_brace, attributes, docs)
        if self.file_kind == "action":
            return self.parse_action_body(name, open_brace, attributes, docs)
        fields, constants = self.parse_members(name.text, open_brace)
        return MessageDecl(name.text, name.span, fields, constants, attributes, docs)

    # -- messages ------------------------------------------------------------------------------
    def parse_block(self, open_brace: Token, what: str, parse_entry) -> None:
        """Calls parse_entry for each entry up to the closing '}', resynchronising after errors."""
        while True:
            token = self.peek()
            if token.is_punct("}"):
                self.advance()
                return
            if token.kind is Kind.EOF:
                self.reporter.error(open_brace.span, f"unterminated {what}: expected '}}'",
                                    "every '{' needs a matching '}'")
                return
            start = self.pos
            try:
                parse_entry()
            except _Recover:
                self.skip_to_member_end()
            if self.pos == start:
                self.advance()

    def parse_members(self, owner: str, open_brace: Token) -> tuple[tuple[FieldDecl, ...], tuple[ConstDecl, ...]]:
        fields: list[FieldDecl] = []
        constants: list[ConstDecl] = []

        def entry() -> None:
            member = self.parse_member(owner)
            (constants if isinstance(member, ConstDecl) else fields).append(member)
            self.expect_member_end(member.name)

        self.parse_block(open_brace, f"block of '{owner}'", entry)
        return tuple(fields), tuple(constants)

    def expect_member_end(self, member: str) -> None:
        if self.accept_punct(",") or self.peek().is_punct("}"):
            return
        token = self.peek()
        looks_like_next_member = token.kind in (Kind.IDENT, Kind.DOC) or token.is_punct("#[")
        self.reporter.error(token.span, f"expected ',' or '}}' after '{member}', found {token.describe()}",
                            "separate members with ','")
        if not looks_like_next_member:
            raise _Recover()

    def parse_member(self, owner: str) -> FieldDecl | ConstDecl:
        attributes, docs = self.parse_prefix()
        if self.peek().is_word("const"):
            self.advance()
            name = self.expect_ident("a constant name")
            self.expect_punct(":", f"after constant name '{name.text}'",
                              f"a constant reads: const {name.text}: u32 = 1")
            type_expr = self.parse_type()
            self.expect_punct("=", f"after the type of constant '{name.text}'", "a constant needs a value")
            value = self.parse_literal()
            return ConstDecl(name.text, name.span, type_expr, value, attributes, docs)
        if self.peek().is_word("pub"):
            self.advance()
        name = self.expect_ident(f"a field name in '{owner}'")
        colon = self.peek()
        if not colon.is_punct(":"):
            hint = f"a field reads: {name.text}: f64"
            if colon.kind is Kind.IDENT:
                hint = f"write '{name.text}: {colon.text}'"
            raise self.fail(colon.span, f"expected ':' after field name '{name.text}', found {colon.describe()}", hint)
        self.advance()
        type_expr = self.parse_type()
        default = self.parse_literal() if self.accept_punct("=") else None
        return FieldDecl(name.text, name.span, type_expr, default, attributes, docs)

    # -- types and literals --------------------------------------------------------------------
    def nested(self, token: Token, what: str) -> None:
        """Enters one level of a nested type or list; past MAX_NESTING, reports it and gives up."""
        if self.nesting >= MAX_NESTING:
            raise self.fail(token.span, f"{what} nest more than {MAX_NESTING} deep",
                            "flatten it, or name the inner part as a message of its own")

    def parse_type(self) -> TypeExpr:
        self.nested(self.peek(), "types")
        self.nesting += 1
        try:
            return self.parse_type_inside()
        finally:
            self.nesting -= 1

    def parse_type_inside(self) -> TypeExpr:
        token = self.peek()
        if token.is_punct("["):
            self.advance()
            element = self.parse_type()
            self.expect_punct(";", "between an array's element type and its length",
                              "a fixed array reads: [f32; 360]")
            length = self.parse_literal()
            self.expect_punct("]", "to close the array type")
            return TypeExpr(("[]",), token.span, element=element, length=length)
        if token.kind is not Kind.IDENT:
            raise self.fail(token.span, f"expected a type, found {token.describe()}")
        path = [self.advance().text]
        while self.peek().is_punct("::") or (self.peek().is_punct(".") and self.peek(1).kind is Kind.IDENT):
            self.advance()
            path.append(self.expect_ident("a name after '::'").text)
        args: list[TypeExpr | Literal] = []
        if self.accept_punct("<"):
            while True:
                if self.peek().kind in (Kind.INT, Kind.FLOAT) or self.peek().is_punct("-"):
                    args.append(self.parse_literal())
                else:
                    args.append(self.parse_type())
                if not self.accept_punct(","):
                    break
            self.expect_punct(">", f"to close the arguments of '{'::'.join(path)}'")
        end = self.tokens[self.pos - 1].span
        length = end.col + end.length - token.span.col if end.line == token.span.line else token.span.length
        return TypeExpr(tuple(path), Span(token.span.source, token.span.line, token.span.col, length), tuple(args))

    def parse_literal(self) -> Literal:
        self.nested(self.peek(), "values")
        self.nesting += 1
        try:
            return self.parse_literal_inside()
        finally:
            self.nesting -= 1

    def parse_literal_inside(self) -> Literal:
        token = self.peek()
        if token.is_punct("-"):
            self.advance()
            number = self.peek()
            if number.kind not in (Kind.INT, Kind.FLOAT):
                raise self.fail(number.span, f"expected a number after '-', found {number.describe()}")
            self.advance()
            span = Span(token.span.source, token.span.line, token.span.col, number.span.col + number.span.length - token.span.col)
            return Literal("int" if number.kind is Kind.INT else "float", -number.value, span)
        if token.kind is Kind.INT:
            self.advance()
            return Literal("int", token.value, token.span)
        if token.kind is Kind.FLOAT:
            self.advance()
            return Literal("float", token.value, token.span)
        if token.kind is Kind.STRING:
            self.advance()
            return Literal("string", token.value, token.span)
        if token.is_word("true") or token.is_word("false"):
            self.advance()
            return Literal("bool", token.text == "true", token.span)
        if token.kind is Kind.IDENT:
            path = [self.advance().text]
            while self.accept_punct("::"):
                path.append(self.expect_ident("a name after '::'").text)
            end = self.tokens[self.pos - 1].span
            return Literal("path", tuple(path), Span(token.span.source, token.span.line, token.span.col,
                                                      end.col + end.length - token.span.col))
        if token.is_punct("["):
            self.advance()
            items: list[Literal] = []
            while not self.peek().is_punct("]"):
                items.append(self.parse_literal())
                if not self.accept_punct(","):
                    break
            self.expect_punct("]", "to close the list")
            return Literal("list", tuple(items), token.span)
        raise self.fail(token.span, f"expected a value, found {token.describe()}")

    def parse_dotted_path(self, what: str) -> tuple[str, Span]:
        first = self.expect_ident(what)
        parts = [first.text]
        while self.peek().is_punct(".") or self.peek().is_punct("::"):
            self.advance()
            parts.append(self.expect_ident(what).text)
        return ".".join(parts), first.span

    # -- enums ---------------------------------------------------------------------------------
    def parse_enum(self, attributes, docs) -> EnumDecl:
        self.advance()
        name = self.expect_ident("an enum name")
        underlying = None
        if self.accept_punct(":"):
            underlying = self.parse_type()
        open_brace = self.expect_punct("{", f"after enum '{name.text}'",
                                       f"an enum reads: enum {name.text}: u8 {{ A = 0, B = 1 }}")
        variants: list[EnumVariant] = []

        def entry() -> None:
            _, variant_docs = self.parse_prefix()
            variant = self.expect_ident(f"an enumerator name in '{name.text}'")
            value = self.parse_literal() if self.accept_punct("=") else None
            variants.append(EnumVariant(variant.text, variant.span, value, variant_docs))
            self.expect_member_end(variant.text)

        self.parse_block(open_brace, f"enum '{name.text}'", entry)
        return EnumDecl(name.text, name.span, underlying, tuple(variants), attributes, docs)

    # -- services ------------------------------------------------------------------------------
    def parse_service_body(self, name: Token, open_brace: Token, attributes, docs) -> ServiceDecl:
        parts: dict[str, MessageDecl] = {}
        action_blocks: list[str] = []  # an action written in a .hsrv: one error says so, not three

        def entry() -> None:
            part_attributes, part_docs = self.parse_prefix()
            part = self.expect_ident("'request' or 'response'")
            kind = part.text
            if kind not in ("request", "response"):
                guess = near_miss(kind, ["request", "response"])
                if kind in ACTION_BLOCKS:
                    action_blocks.append(kind)
                self.reporter.error(part.span, f"expected 'request' or 'response', found '{kind}'",
                                    f"did you mean '{guess}'?" if guess else
                                    "actions go in a .haction file" if kind in ACTION_BLOCKS else
                                    "a service holds a request { ... } and a response { ... } block")
                if guess is None or guess in parts:
                    self.skip_block()
                    return
                kind = guess  # read the block as the part it most likely is, so nothing cascades
            if kind in parts:
                self.reporter.error(part.span, f"service '{name.text}' has two '{kind}' blocks")
            block = self.expect_punct("{", f"after '{part.text}'")
            type_name = name.text + kind.capitalize()
            fields, constants = self.parse_members(type_name, block)
            parts[kind] = MessageDecl(type_name, part.span, fields, constants, part_attributes, part_docs)
            self.accept_punct(",")

        self.parse_block(open_brace, f"service '{name.text}'", entry)
        for missing in ("request", "response"):
            if missing not in parts:
                if not action_blocks:
                    self.reporter.error(name.span, f"service '{name.text}' has no '{missing}' block",
                                        f"add '{missing} {{ }}' (it may be empty)")
                parts[missing] = MessageDecl(name.text + missing.capitalize(), name.span, (), (), (), ())
        return ServiceDecl(name.text, name.span, parts["request"], parts["response"], attributes, docs)

    # -- actions -------------------------------------------------------------------------------
    def parse_action_body(self, name: Token, open_brace: Token, attributes, docs) -> ActionDecl:
        """`Navigate { goal { ... } result { ... } feedback { ... } }`: each block once, in any
        order, read as the message `Navigate<Block>` (its docs and attributes are the message's)."""
        parts: dict[str, MessageDecl] = {}
        expected = "'goal', 'result' or 'feedback'"

        def entry() -> None:
            part_attributes, part_docs = self.parse_prefix()
            part = self.expect_ident(expected)
            kind = part.text
            if kind not in ACTION_BLOCKS:
                guess = near_miss(kind, list(ACTION_BLOCKS))
                self.reporter.error(part.span, f"expected {expected}, found '{kind}'",
                                    f"did you mean '{guess}'?" if guess else
                                    "an action holds a goal { ... }, a result { ... } and a feedback { ... } block")
                if guess is None or guess in parts:
                    self.skip_block()
                    return
                kind = guess  # read the block as the part it most likely is, so nothing cascades
            if kind in parts:
                self.reporter.error(part.span, f"action '{name.text}' has two '{kind}' blocks",
                                    notes=(Note(parts[kind].span, "first block here"),))
            block = self.expect_punct("{", f"after '{part.text}'")
            type_name = name.text + kind.capitalize()
            fields, constants = self.parse_members(type_name, block)
            parts.setdefault(kind, MessageDecl(type_name, part.span, fields, constants, part_attributes, part_docs))
            self.accept_punct(",")

        self.parse_block(open_brace, f"action '{name.text}'", entry)
        for missing in ACTION_BLOCKS:
            if missing not in parts:
                self.reporter.error(name.span, f"action '{name.text}' has no '{missing}' block",
                                    f"add '{missing} {{ }}' (it may be empty)")
                parts[missing] = MessageDecl(name.text + missing.capitalize(), name.span, (), (), (), ())
        return ActionDecl(name.text, name.span, parts["goal"], parts["result"], parts["feedback"], attributes, docs)


    # -- nodes ---------------------------------------------------------------------------------
    def parse_node(self, attributes, docs) -> NodeDecl:
        name = self.peek()
        if name.kind is not Kind.IDENT:
            raise self.fail(name.span, f"expected a node name, found {name.describe()}",
                            "a node reads: MotorController { name: \"motor\", sub { ... } pub { ... } }")
        self.advance()
        open_brace = self.expect_punct("{", f"after '{name.text}'", f"a node reads: {name.text} {{ ... }}")
        settings: list[NodeSettingDecl] = []
        blocks: list[tuple[str, Span, tuple[NodeEndpointDecl, ...]]] = []
        data: list[FieldDecl] = []
        params: list[FieldDecl] = []
        params_block: list[Token] = []

        def entry() -> None:
            word = self.expect_ident(f"a setting or a block (sub, pub, client, server, data, params) in '{name.text}'")
            if self.peek().is_punct("{"):
                block = self.advance()
                if word.text in ("data", "params"):
                    fields, constants = self.parse_members(f"{word.text} of '{name.text}'", block)
                    for constant in constants:
                        self.reporter.error(constant.span,
                                            f"'{word.text}' of node '{name.text}' holds fields, not constants",
                                            "declare constants in a message schema")
                    if word.text == "data":
                        data.extend(fields)
                    elif params_block:
                        # One block, so that a node's parameters read in one place in declaration order.
                        self.reporter.error(word.span, f"node '{name.text}' has two 'params' blocks",
                                            "declare every parameter in one params { } block",
                                            (Note(params_block[0].span, "first block here"),))
                    else:
                        params_block.append(word)
                        params.extend(fields)
                elif word.text in NODE_BLOCKS:
                    blocks.append((word.text, word.span, self.parse_endpoints(name.text, word.text, block)))
                else:
                    guess = near_miss(word.text, list(NODE_BLOCKS) + ["data", "params"])
                    self.reporter.error(word.span, f"unknown block '{word.text}' in node '{name.text}'",
                                        f"did you mean '{guess}'?" if guess else
                                        "a node's blocks are sub, pub, client, server, data and params")
                    self.parse_block(block, f"block '{word.text}'", self.skip_to_member_end)
                self.accept_punct(",")
                return
            self.expect_punct(":", f"after setting '{word.text}'", f"a setting reads: {word.text}: value")
            settings.append(self.parse_setting(word))
            self.expect_member_end(word.text)

        self.parse_block(open_brace, f"node '{name.text}'", entry)
        return NodeDecl(name.text, name.span, tuple(settings), tuple(blocks), tuple(data), attributes, docs,
                        tuple(params))

    def parse_setting(self, word: Token) -> NodeSettingDecl:
        value = self.parse_literal()
        unit = None
        if value.kind in ("int", "float") and self.peek().kind is Kind.IDENT:
            token = self.advance()
            unit = (token.text, token.span)
        arguments = None
        if value.kind == "path" and self.peek().is_punct("{"):
            open_brace = self.advance()
            found: list[NodeSettingDecl] = []

            def argument() -> None:
                key = self.expect_ident(f"an argument name of '{'::'.join(value.value)}'")
                self.expect_punct(":", f"after argument '{key.text}'", f"an argument reads: {key.text}: value")
                found.append(self.parse_setting(key))
                self.expect_member_end(key.text)

            self.parse_block(open_brace, f"arguments of '{'::'.join(value.value)}'", argument)
            arguments = tuple(found)
        return NodeSettingDecl(word.text, word.span, value, unit, arguments)

    def parse_endpoints(self, node: str, kind: str, open_brace: Token) -> tuple[NodeEndpointDecl, ...]:
        entries: list[NodeEndpointDecl] = []
        is_topic = kind in ("sub", "pub")
        shape = "cmd: horus::msg::CmdVel -> \"cmd_vel\"" if is_topic else "pose: my_robot::srv::GetRobotPose"

        def entry() -> None:
            attributes, docs = self.parse_prefix()
            member = self.expect_ident(f"a member name in the '{kind}' block of '{node}'")
            colon = self.peek()
            if not colon.is_punct(":"):
                raise self.fail(colon.span, f"expected ':' after '{member.text}', found {colon.describe()}",
                                f"an entry reads: {shape}")
            self.advance()
            type_expr = self.parse_type()
            topic = None
            arrow = self.accept_punct("->")
            if arrow is not None:
                target = self.peek()
                if target.kind is not Kind.STRING:
                    raise self.fail(target.span, f"expected a quoted topic name after '->', found {target.describe()}",
                                    f"an entry reads: {shape}")
                self.advance()
                topic = Literal("string", target.value, target.span)
                if not is_topic:
                    self.reporter.error(arrow.span, f"a '{kind}' entry takes no topic name",
                                        "a service's topics come from its name")
            entries.append(NodeEndpointDecl(member.text, member.span, type_expr, topic, attributes, docs))
            self.expect_member_end(member.text)

        self.parse_block(open_brace, f"'{kind}' block of '{node}'", entry)
        return tuple(entries)


def parse(source: Source, reporter: Reporter, file_kind: str) -> FileSyntax:
    return Parser(source, reporter, file_kind).parse_file()
