#!/usr/bin/env python3
"""Checks every #include against the layering table of docs/architecture.md.

The table "Layering: which folder may include which" (its section 2) has one
row per source folder: capture_daemon, proto, tests, bench, fuzz, server (the
files at server/'s root), and clients/<x>, common/<x>, server/<x> with their
own subfolders. Its second column lists the folders the row's code may
include (`–`: none; `anything`), its third what test code (files named
*_test.cc, files under a testing/ folder) may include besides. A folder may
always include itself.

Every quoted #include of every .h/.cc/.cpp file maps to a folder by its path
from the repository root (or from the file's folder when only that exists);
generated headers (reenact/v1/*.pb.h, grpc/health/v1/...) belong to proto,
other paths (absl/..., vendors') are not checked. It prints, one a line:

- FILE:LINE: each include the table does not allow;
- each folder-level cycle of production code (test code is built into test
  programs only and left out), through each edge the table does not allow;
- a source folder missing from the table, and any cycle in the table itself;

then a summary line, and exits 1 if it found anything, else 0. With --list
it prints the includes the code has instead, as rows of the table.

To fix a finding, change the code: include only what the folder may (move
the shared piece down to a folder both may include, or pass it in from
above). When the dependency is intended, add it to the folder's row in
docs/architecture.md instead, keeping the table free of cycles.
Standard library only.
"""

import argparse
import collections
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOC = os.path.join("docs", "architecture.md")
# Top-level source folders; the split ones give one folder per subfolder.
SOURCE_ROOTS = ("capture_daemon", "clients", "common", "server", "proto",
                "tests", "bench", "fuzz")
SPLIT_ROOTS = ("clients", "common", "server")
# First path parts of the headers generated from proto/.
GENERATED_ROOTS = ("reenact", "grpc")
EXTENSIONS = (".h", ".cc", ".cpp")
SKIPPED_DIRS = ("node_modules",)
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')
TABLE_HEADER = re.compile(r"^\|\s*folder\s*\|\s*may include\s*\|")
ANYTHING = "anything"


def folder_of(path):
    """The layering folder of a repository path, or None outside them."""
    parts = path.split("/")
    if parts[0] in GENERATED_ROOTS:
        return "proto"
    if parts[0] not in SOURCE_ROOTS:
        return None
    if parts[0] in SPLIT_ROOTS and len(parts) > 2:
        return parts[0] + "/" + parts[1]
    return parts[0]


def is_test_code(path):
    """Whether a file is built into test programs only."""
    parts = path.split("/")
    return parts[-1].endswith("_test.cc") or "testing" in parts[:-1]


def read_table(doc_path):
    """{folder: (may include, tests may also include)}, each a set of
    folders or ANYTHING, from the first table headed `| folder | may
    include |` in the document."""
    rows, in_table = {}, False
    with open(doc_path, encoding="utf-8") as doc:
        for line in doc:
            if not in_table:
                in_table = bool(TABLE_HEADER.match(line))
                continue
            if not line.startswith("|"):
                break
            cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
            if set(cells[0]) <= set("-: "):
                continue  # the |---| line
            rows[cells[0].strip("`")] = tuple(
                ANYTHING if ANYTHING in cell else set(re.findall(r"`([^`]+)`", cell))
                for cell in (cells + ["", ""])[1:3])
    return rows


def includes_of(path):
    """(line number, included path) of each quoted #include in a file."""
    with open(os.path.join(ROOT, path), encoding="utf-8", errors="replace") as source:
        for number, text in enumerate(source, 1):
            match = INCLUDE.match(text)
            if not match:
                continue
            included = match.group(1)
            local = os.path.normpath(os.path.join(os.path.dirname(path), included))
            if (not os.path.exists(os.path.join(ROOT, included))
                    and os.path.exists(os.path.join(ROOT, local))):
                included = local.replace(os.sep, "/")  # relative to the file
            yield number, included


def scan():
    """The source folders, the number of files, and every project include:
    (file, line, included path, from folder, to folder, test code)."""
    folders, files, includes = set(), 0, []
    for top in SOURCE_ROOTS:
        for dirpath, dirnames, filenames in os.walk(os.path.join(ROOT, top)):
            dirnames[:] = sorted(d for d in dirnames if d not in SKIPPED_DIRS)
            for name in sorted(n for n in filenames if n.endswith(EXTENSIONS)):
                path = os.path.relpath(os.path.join(dirpath, name), ROOT)
                path = path.replace(os.sep, "/")
                files += 1
                folders.add(folder_of(path))
                for number, included in includes_of(path):
                    target = folder_of(included)
                    if target is not None:
                        includes.append((path, number, included, folder_of(path),
                                         target, is_test_code(path)))
    return folders, files, includes


def loop_through(edges, source, target):
    """The shortest cycle source -> target -> ... -> source in a graph
    {folder: set of folders}, as a list of folders, or None (breadth first
    from target)."""
    previous, queue = {target: None}, collections.deque([target])
    while queue:
        node = queue.popleft()
        if node == source:
            path = []
            while node is not None:
                path.append(node)
                node = previous[node]
            return [source] + path[::-1]
        for succ in sorted(edges.get(node, ())):
            if succ not in previous:
                previous[succ] = node
                queue.append(succ)
    return None


def allows(rows, source, target, test):
    """Whether the table lets (test) code of `source` include `target`."""
    if source == target:
        return True
    row = rows.get(source, (set(), set()))
    return any(allowed == ANYTHING or target in allowed
               for allowed in (row if test else row[:1]))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--list", action="store_true",
                        help="print each folder's actual includes as table rows")
    args = parser.parse_args()
    folders, files, includes = scan()

    # The folder graph of production code, with one include for each edge,
    # and that of all code.
    production, every, example = {}, {}, {}
    for path, number, _, source, target, test in includes:
        if source != target:
            every.setdefault(source, set()).add(target)
            if not test:
                example.setdefault((source, target), "%s:%d" % (path, number))
                production.setdefault(source, set()).add(target)
    if args.list:
        cell = lambda deps: ", ".join("`%s`" % d for d in sorted(deps)) or "–"
        for folder in sorted(folders):
            only = production.get(folder, set())
            print("| `%s` | %s | %s |" % (folder, cell(only),
                                          cell(every.get(folder, set()) - only)))
        return 0

    rows, findings = read_table(os.path.join(ROOT, DOC)), []
    if not rows:
        print("%s: no table headed | folder | may include |" % DOC)
        return 1
    for folder in sorted(folders - set(rows)):
        findings.append("%s: folder %s is not in the layering table" % (DOC, folder))
    # The table's own order must have no cycle (one shown of those that
    # share folders).
    intended = {folder: row[0] for folder, row in rows.items() if row[0] != ANYTHING}
    seen = set()
    for source in sorted(intended):
        for target in sorted(intended[source]):
            loop = loop_through(intended, source, target)
            if loop and not seen.intersection(loop):
                seen.update(loop)
                findings.append("%s: the layering table has a cycle: %s"
                                % (DOC, " -> ".join(loop)))
    for path, number, included, source, target, test in includes:
        if not allows(rows, source, target, test):
            findings.append("%s:%d: %s includes %s, which %s%s may not include"
                            % (path, number, path, included,
                               "test code in " if test else "", source))

    # Folder-level cycles of production code, each shown through an edge of
    # it that the table does not allow (with an acyclic table, every cycle
    # has one), with one include for each edge.
    for source in sorted(production):
        for target in sorted(production[source]):
            loop = loop_through(production, source, target)
            if loop and not allows(rows, source, target, False):
                findings.append("cycle: %s  (%s)" % (" -> ".join(loop), ", ".join(
                    example[edge] for edge in zip(loop, loop[1:]))))

    for finding in findings:
        print(finding)
    print("%d files and %d includes of project folders checked; findings: %d"
          % (files, len(includes), len(findings)))
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
