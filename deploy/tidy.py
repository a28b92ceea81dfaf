#!/usr/bin/env python3
"""clang-tidy over the C++ sources, with the checks of the root .clang-tidy.

  deploy/tidy.py [--all] [--build DIR] [--jobs N] [--clean-list FILE]
                 [--write-clean-list FILE] [FILE ...]

Checks every production source (each tracked .cc that is neither a test, a
benchmark, a fuzz target nor a test helper) and the project headers they
include; --all adds the tests; FILEs check just those. Needs the build's
compile_commands.json (deploy/build.sh writes it) and clang-tidy 14
(Debian's clang-tidy). Exits 1 when clang-tidy warns, 2 on bad use.

A source is not checked again while its key stays as it was when it last
passed. The key hashes the source's preprocessed text (one preprocessor run),
its compile command, .clang-tidy and the clang-tidy version, with the
checkout's and the build folder's absolute paths replaced by fixed
placeholders and -Werror left out (clang-tidy runs with -Wno-error): a clone
elsewhere, built with or without REENACT_WERROR, has the same keys. Sources
known clean are those whose key is in the local cache ($XDG_CACHE_HOME/
reenact/tidy, else ~/.cache/reenact/tidy) or in the --clean-list FILE; a run
after a small change costs seconds, a first run about 20 minutes on two
cores.

The clean list, deploy/tidy-clean.txt, is tracked: one "<sha256 key>
<source path>" line per source known clean ('#' starts a comment). CI passes
it with --clean-list, so it runs clang-tidy only on sources whose key is not
in the list; its cost is then about one preprocessor run per source. A change
to any production source or project header changes keys, so before a commit
refresh the list:

  python3 deploy/tidy.py --clean-list deploy/tidy-clean.txt \
      --write-clean-list deploy/tidy-clean.txt

--write-clean-list rewrites FILE with every source of this run found clean
(sources with warnings are left out, and the run still fails); it needs the
whole tree (no FILE arguments). A stale list costs CI time, never
correctness: a source not in it is simply checked.
"""
import argparse
import concurrent.futures
import hashlib
import json
import os
import shlex
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NOT_PRODUCTION = ("_test.cc",)
NOT_PRODUCTION_DIRS = ("bench/", "fuzz/", "tests/")


def is_production(path):
    if path.endswith(NOT_PRODUCTION) or path.startswith(NOT_PRODUCTION_DIRS):
        return False
    return "/testing/" not in path


def path_placeholders(build):
    """(absolute path, placeholder) pairs, longest path first.

    The build folder usually lies inside the checkout, so it is replaced
    first; both the given and the symlink-free spelling of each are."""
    pairs = {}
    for path, placeholder in ((build, "@BUILD@"), (ROOT, "@ROOT@")):
        for spelling in (os.path.abspath(path), os.path.realpath(path)):
            pairs.setdefault(spelling, placeholder)
    return sorted(pairs.items(), key=lambda pair: -len(pair[0]))


def normalise(text, placeholders):
    for path, placeholder in placeholders:
        text = text.replace(path, placeholder)
    return text


def cache_key(entry, config, version, placeholders):
    """Hash of what decides clang-tidy's answer for one source.

    Independent of where the checkout and the build folder lie: their
    absolute paths (in the flags, and in the preprocessed text wherever
    __FILE__ expands, as in the generated .pb.h) become placeholders. -Werror
    is left out too, as clang-tidy runs with -Wno-error (see check)."""
    args = entry.get("arguments") or shlex.split(entry["command"])
    # The preprocessor's view of the source: the same flags, -E, no output file.
    pre, skip = [], False
    for arg in args:
        if skip:
            skip = False
            continue
        if arg in ("-o", "-MF", "-MT", "-MQ"):
            skip = True
            continue
        if arg in ("-c", "-MD", "-MMD"):
            continue
        pre.append(arg)
    out = subprocess.run(pre + ["-E", "-P"], cwd=entry["directory"], capture_output=True)
    flags = [normalise(arg, placeholders) for arg in args if arg != "-Werror"]
    text = out.stdout
    for path, placeholder in placeholders:
        text = text.replace(path.encode(), placeholder.encode())
    digest = hashlib.sha256()
    for part in (config, version, json.dumps(flags).encode(), text):
        digest.update(hashlib.sha256(part).digest())
    return digest.hexdigest() if out.returncode == 0 else None


def main():
    parser = argparse.ArgumentParser(usage=__doc__.split("\n\n")[1].strip())
    parser.add_argument("--all", action="store_true")
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    parser.add_argument("--clean-list", metavar="FILE")
    parser.add_argument("--write-clean-list", metavar="FILE")
    parser.add_argument("files", nargs="*")
    options = parser.parse_args()

    tidy = shutil.which("clang-tidy-14") or shutil.which("clang-tidy")
    if not tidy:
        print("tidy.py: clang-tidy is not installed (apt-get install clang-tidy)", file=sys.stderr)
        return 2
    database = os.path.join(options.build, "compile_commands.json")
    if not os.path.exists(database):
        print(f"tidy.py: no {database}; build first (deploy/build.sh)", file=sys.stderr)
        return 2
    if options.write_clean_list and options.files:
        print("tidy.py: --write-clean-list needs the whole tree, not FILEs", file=sys.stderr)
        return 2
    known_clean = set()
    if options.clean_list and os.path.exists(options.clean_list):
        with open(options.clean_list) as f:
            for line in f:
                fields = line.split("#", 1)[0].split()
                if fields:
                    known_clean.add(fields[0])
    elif options.clean_list:
        print(f"tidy.py: no {options.clean_list}; checking every source", file=sys.stderr)
    placeholders = path_placeholders(options.build)
    with open(database) as f:
        entries = {os.path.relpath(e["file"], ROOT): e for e in json.load(f)}
    if options.files:
        wanted = [os.path.relpath(os.path.abspath(f), ROOT) for f in options.files]
    else:
        tracked = subprocess.run(["git", "ls-files", "*.cc"], cwd=ROOT, capture_output=True,
                                 text=True, check=True).stdout.split()
        wanted = [f for f in tracked if options.all or is_production(f)]
    missing = [f for f in wanted if f not in entries]
    files = [f for f in wanted if f in entries]
    if missing:
        print(f"tidy.py: {len(missing)} sources are not built here and were not checked: "
              + ", ".join(missing), file=sys.stderr)

    with open(os.path.join(ROOT, ".clang-tidy"), "rb") as f:
        config = f.read()
    version = subprocess.run([tidy, "--version"], capture_output=True).stdout
    cache = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"),
                         "reenact", "tidy")
    os.makedirs(cache, exist_ok=True)

    def check(path):
        """(path, key, clean, report, checked): checked is False when known clean."""
        entry = entries[path]
        key = cache_key(entry, config, version, placeholders)
        marker = os.path.join(cache, key) if key else None
        if key and (key in known_clean or os.path.exists(marker)):
            return path, key, True, "", False
        # -Wno-error: the key leaves -Werror out, so the answer must not depend on it.
        run = subprocess.run([tidy, "-p", options.build, "--quiet", "--extra-arg=-Wno-error", path],
                             cwd=ROOT, capture_output=True, text=True)
        warnings = [line for line in run.stdout.splitlines() if ": warning: " in line
                    or ": error: " in line]
        clean = run.returncode == 0 and not warnings
        if clean and marker:
            open(marker, "w").close()
        return path, key, clean, run.stdout if not clean else "", True

    failed, clean_keys, checked = [], [], 0
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, options.jobs)) as pool:
        for path, key, clean, report, ran in pool.map(check, files):
            checked += ran
            if not clean:
                failed.append(path)
                sys.stdout.write(report)
            elif key:
                clean_keys.append((path, key))
    if options.write_clean_list:
        with open(options.write_clean_list, "w") as f:
            f.write("# Sources clang-tidy found clean: <key> <path> (deploy/tidy.py"
                    " --write-clean-list writes it).\n")
            for path, key in sorted(clean_keys):
                f.write(f"{key} {path}\n")
        print(f"tidy.py: wrote {len(clean_keys)} clean sources to {options.write_clean_list}"
              + (f" ({len(failed)} with warnings left out)" if failed else ""), file=sys.stderr)
    if failed:
        print(f"tidy.py: clang-tidy warns in {len(failed)} of {len(files)} sources: "
              + ", ".join(failed), file=sys.stderr)
        return 1
    print(f"tidy.py: {len(files)} sources are clean by .clang-tidy"
          f" ({len(files) - checked} known clean, {checked} checked)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
