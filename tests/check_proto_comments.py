#!/usr/bin/env python3
"""Checks that every declaration of the .proto files has a comment of its own:

  python3 tests/check_proto_comments.py proto/reenact/v1 [more dirs or files]

Every message, enum, service, field (map fields and fields of a oneof
included), enum value and rpc needs either

- a leading comment: `//` lines (or a `/* */` block) directly above it, the
  last one on the line right before the declaration, no blank line between,
  each starting its own line (a trailing comment of the declaration above
  does not count), or
- a trailing comment: `//` (or `/* */`) after the declaration's `;` (for a
  message, enum, service or rpc with a body: after its `{`) on the same line,
  or on a line of the declaration itself when it spans several lines.

A comment that sits above a group of fields belongs to the first of them
only. A comment without a letter or digit (`//` alone, `// ----`) does not
count. `syntax`, `package`, `import`, `option` and `reserved` statements
need no comment, nor do oneofs themselves (their fields do).

Prints every declaration without a comment as FILE:LINE: kind Full.Name and
the counts it checked; exits 1 when any lacks a comment or a file cannot be
parsed, 0 otherwise. Standard library only: the .proto text is parsed here.
"""

import os
import re
import sys

BLOCK_KINDS = ("message", "enum", "service", "oneof", "extend")
IGNORED_STATEMENTS = ("syntax", "edition", "package", "import", "option",
                      "reserved", "extensions")
FIELD_LABELS = ("optional", "repeated", "required")
CHECKED_KINDS = ("message", "enum", "service", "field", "enum value", "rpc")


class ProtoError(Exception):
    """A .proto text this checker cannot follow; line 0: the whole file."""

    def __init__(self, line, message):
        super().__init__(message)
        self.line = line
        self.message = message


class Token:
    __slots__ = ("kind", "text", "line", "end_line", "first_on_line")

    def __init__(self, kind, text, line, end_line, first_on_line):
        self.kind = kind  # "ident", "number", "string", "symbol", "comment"
        self.text = text
        self.line = line
        self.end_line = end_line
        self.first_on_line = first_on_line

    def __repr__(self):
        return "Token(%s, %r, %d)" % (self.kind, self.text, self.line)


_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")
_NUMBER = re.compile(r"[-+]?(0[xX][0-9A-Fa-f]+|[0-9]*\.?[0-9]+([eE][-+]?[0-9]+)?)"
                     r"|[-+]?(inf|nan)\b")


def tokenize(text):
    tokens = []
    i = 0
    line = 1
    n = len(text)
    line_has_token = False
    while i < n:
        c = text[i]
        if c == "\n":
            line += 1
            line_has_token = False
            i += 1
            continue
        if c in " \t\r\f\v":
            i += 1
            continue
        start_line = line
        first = not line_has_token
        if text.startswith("//", i):
            j = text.find("\n", i)
            if j < 0:
                j = n
            tokens.append(Token("comment", text[i:j], start_line, start_line, first))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            if j < 0:
                raise ProtoError(start_line, "unterminated /* comment")
            body = text[i:j + 2]
            line += body.count("\n")
            tokens.append(Token("comment", body, start_line, line, first))
            i = j + 2
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                if text[j] == "\\":
                    j += 1
                elif text[j] == "\n":
                    raise ProtoError(start_line, "unterminated string")
                j += 1
            if j >= n:
                raise ProtoError(start_line, "unterminated string")
            tokens.append(Token("string", text[i:j + 1], start_line, start_line, first))
            i = j + 1
        else:
            m = _IDENT.match(text, i)
            if m:
                tokens.append(Token("ident", m.group(0), start_line, start_line, first))
                i = m.end()
            else:
                m = _NUMBER.match(text, i)
                if m and m.end() > i:
                    tokens.append(Token("number", m.group(0), start_line, start_line, first))
                    i = m.end()
                else:
                    tokens.append(Token("symbol", c, start_line, start_line, first))
                    i += 1
        # Whatever follows on this line (after a multi-line /* */: on its last
        # line) is not first on its line.
        line_has_token = True
    return tokens


def comment_says_something(comment_text):
    if comment_text.startswith("//"):
        body = comment_text[2:]
    else:
        body = comment_text[2:-2]
    return re.search(r"[A-Za-z0-9]", body) is not None


class Declaration:
    def __init__(self, kind, name, line):
        self.kind = kind
        self.name = name
        self.line = line
        self.commented = False


class Parser:
    def __init__(self, path, tokens):
        self.path = path
        self.all_tokens = tokens
        # Indices of non-comment tokens, for walking the grammar.
        self.code = [i for i, t in enumerate(tokens) if t.kind != "comment"]
        self.pos = 0
        self.declarations = []

    # --- token access -------------------------------------------------
    def at_end(self):
        return self.pos >= len(self.code)

    def peek(self, offset=0):
        k = self.pos + offset
        if k >= len(self.code):
            return None
        return self.all_tokens[self.code[k]]

    def next(self):
        if self.at_end():
            last = self.all_tokens[-1].line if self.all_tokens else 0
            raise ProtoError(last, "unexpected end of file")
        t = self.all_tokens[self.code[self.pos]]
        self.pos += 1
        return t

    def error(self, token, what):
        raise ProtoError(token.line, "%s (at %r)" % (what, token.text))

    # --- comments -----------------------------------------------------
    def has_leading_comment(self, code_pos):
        """Comment lines directly above the token at code index code_pos."""
        tok_index = self.code[code_pos]
        first = self.all_tokens[tok_index]
        expected_line = first.line  # a comment must end on this line - 1
        k = tok_index - 1
        saying = False
        found = False
        while k >= 0 and self.all_tokens[k].kind == "comment":
            c = self.all_tokens[k]
            if not c.first_on_line:
                # A trailing comment of whatever precedes it on its line; it
                # may still lead a declaration on the same line (/* x */ a).
                if c.end_line == first.line and not found:
                    if comment_says_something(c.text):
                        return True
                break
            if c.end_line == first.line and not found:
                # /* x */ int32 a = 1;  (a comment before it on its own line)
                found = True
                saying = saying or comment_says_something(c.text)
                expected_line = c.line
                k -= 1
                continue
            if c.end_line != expected_line - 1:
                break  # a blank line (or code) between
            found = True
            saying = saying or comment_says_something(c.text)
            expected_line = c.line
            k -= 1
        return found and saying

    def has_trailing_comment(self, start_pos, end_pos):
        """A comment among the declaration's tokens (from code index start_pos
        to end_pos, the terminator, inclusive) that follows code on its line,
        or one right after the terminator on the terminator's line."""
        lo = self.code[start_pos]
        hi = self.code[end_pos]
        term = self.all_tokens[hi]
        for k in range(lo + 1, hi):
            t = self.all_tokens[k]
            if t.kind == "comment" and comment_says_something(t.text):
                return True
        k = hi + 1
        while k < len(self.all_tokens) and self.all_tokens[k].kind == "comment":
            t = self.all_tokens[k]
            if t.line != term.end_line:
                break
            if comment_says_something(t.text):
                return True
            k += 1
        return False

    def declare(self, kind, name, start_pos, end_pos):
        d = Declaration(kind, name, self.all_tokens[self.code[start_pos]].line)
        d.commented = (self.has_leading_comment(start_pos)
                       or self.has_trailing_comment(start_pos, end_pos))
        self.declarations.append(d)
        return d

    # --- grammar ------------------------------------------------------
    def skip_balanced(self, open_text, close_text):
        """Skips from an opening symbol (already consumed) to its match."""
        depth = 1
        while depth:
            t = self.next()
            if t.kind == "symbol" and t.text == open_text:
                depth += 1
            elif t.kind == "symbol" and t.text == close_text:
                depth -= 1

    def read_statement(self):
        """Reads up to and including `;` or `{` outside of brackets, skipping
        aggregate values ({ ... } after `=` or `:`). Returns (tokens, end)."""
        start = self.pos
        tokens = []
        while True:
            t = self.next()
            if t.kind == "symbol":
                if t.text == ";":
                    return tokens, t, start
                if t.text == "[":
                    tokens.append(t)
                    self.skip_balanced("[", "]")
                    continue
                if t.text == "{":
                    if tokens and tokens[-1].kind == "symbol" and tokens[-1].text in "=:":
                        self.skip_balanced("{", "}")
                        continue
                    return tokens, t, start
                if t.text == "}":
                    self.error(t, "unexpected }")
            tokens.append(t)

    def parse_file(self):
        self.parse_body("file", "")
        return self.declarations

    def parse_body(self, scope, prefix):
        while not self.at_end():
            t = self.peek()
            if t.kind == "symbol" and t.text == "}":
                if scope == "file":
                    self.error(t, "unmatched }")
                self.next()
                return
            if t.kind == "symbol" and t.text == ";":
                self.next()  # empty statement
                continue
            start = self.pos
            tokens, end, _ = self.read_statement()
            end_pos = self.pos - 1
            if not tokens:
                self.error(end, "empty declaration")
            head = tokens[0].text
            if tokens[0].kind == "ident" and head in IGNORED_STATEMENTS:
                if end.text == "{":
                    self.skip_balanced("{", "}")
                continue
            if head in BLOCK_KINDS and len(tokens) >= 2 and end.text == "{":
                name = tokens[1].text
                full = prefix + name
                if head == "oneof":
                    if scope not in ("message", "extend"):
                        self.error(tokens[0], "oneof outside a message")
                    # The oneof itself needs no comment; its fields do, named
                    # after the message that holds them.
                    self.parse_body("oneof", prefix)
                    continue
                if head == "extend":
                    self.parse_body("extend", prefix)
                    continue
                self.declare(head, full, start, end_pos)
                self.parse_body(head, full + ".")
                continue
            if scope == "service":
                if head != "rpc" or len(tokens) < 2:
                    self.error(tokens[0], "expected rpc in a service")
                self.declare("rpc", prefix + tokens[1].text, start, end_pos)
                if end.text == "{":
                    self.parse_body("rpc", prefix + tokens[1].text + ".")
                continue
            if scope == "rpc":
                self.error(tokens[0], "only options belong in an rpc body")
            if end.text == "{":
                if head == "group" or (len(tokens) > 1 and tokens[1].text == "group"):
                    self.error(tokens[0], "groups are not supported")
                self.error(tokens[0], "unexpected {")
            if scope == "enum":
                if len(tokens) < 3 or tokens[1].text != "=":
                    self.error(tokens[0], "expected NAME = NUMBER in an enum")
                self.declare("enum value", prefix + head, start, end_pos)
                continue
            if scope in ("message", "oneof", "extend"):
                name = self.field_name(tokens)
                self.declare("field", prefix + name, start, end_pos)
                continue
            self.error(tokens[0], "unexpected statement at file level")
        if scope != "file":
            last = self.all_tokens[-1].line if self.all_tokens else 0
            raise ProtoError(last, "unexpected end of file inside a %s" % scope)

    def field_name(self, tokens):
        # [label] type name = number [options];   map<K, V> name = number;
        eq = None
        for k, t in enumerate(tokens):
            if t.kind == "symbol" and t.text == "=":
                eq = k
                break
        if eq is None or eq == 0 or tokens[eq - 1].kind != "ident":
            self.error(tokens[0], "expected a field: [label] type name = number;")
        return tokens[eq - 1].text


def proto_files(arguments):
    files = []
    for argument in arguments:
        if os.path.isdir(argument):
            for root, dirs, names in os.walk(argument):
                dirs.sort()
                for name in sorted(names):
                    if name.endswith(".proto"):
                        files.append(os.path.join(root, name))
        elif os.path.isfile(argument):
            files.append(argument)
        else:
            raise ProtoError(0, "%s: no such file or folder" % argument)
    return files


def main(argv):
    if len(argv) < 2 or argv[1] in ("-h", "--help"):
        sys.stderr.write(__doc__)
        return 2
    try:
        files = proto_files(argv[1:])
    except ProtoError as e:
        print(e.message, file=sys.stderr)
        return 2
    if not files:
        print("no .proto files in %s" % " ".join(argv[1:]), file=sys.stderr)
        return 1
    counts = {k: 0 for k in CHECKED_KINDS}
    missing = {k: 0 for k in CHECKED_KINDS}
    failed = False
    for path in files:
        try:
            with open(path, encoding="utf-8") as f:
                text = f.read()
            declarations = Parser(path, tokenize(text)).parse_file()
        except ProtoError as e:
            print("%s:%d: cannot parse: %s" % (path, e.line, e.message))
            failed = True
            continue
        except (OSError, UnicodeDecodeError) as e:
            print("%s: cannot read: %s" % (path, e))
            failed = True
            continue
        for d in declarations:
            counts[d.kind] += 1
            if not d.commented:
                missing[d.kind] += 1
                print("%s:%d: %s %s" % (path, d.line, d.kind, d.name))
    total = sum(counts.values())
    total_missing = sum(missing.values())
    print("checked %d files: %s" % (len(files), ", ".join(
        "%d %ss" % (counts[k], k) for k in CHECKED_KINDS)))
    if total_missing:
        print("%d of %d declarations lack a comment of their own (%s)" % (
            total_missing, total, ", ".join(
                "%d of %d %ss" % (missing[k], counts[k], k) for k in CHECKED_KINDS
                if missing[k])))
        return 1
    if failed:
        return 1
    print("every one of the %d declarations has a comment of its own" % total)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
