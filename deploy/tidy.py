#!/usr/bin/env python3
"""clang-tidy over the C++ sources, with the checks of the root .clang-tidy.

  deploy/tidy.py [--all] [--build DIR] [--jobs N] [FILE ...]

Checks every production source (each tracked .cc that is neither a test, a
benchmark, a fuzz target nor a test helper) and the project headers they
include; --all adds the tests; FILEs check just those. Needs the build's
compile_commands.json (deploy/build.sh writes it) and clang-tidy 14
(Debian's clang-tidy). Exits 1 when clang-tidy warns, 2 on bad use.

A source is not checked again while its preprocessed text, its compile
command and .clang-tidy stay as they were when it last passed (cache:
$XDG_CACHE_HOME/reenact/tidy, else ~/.cache/reenact/tidy): a run after a
small change costs seconds, a first run about 10 minutes on two cores.
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


def cache_key(entry, config, version):
    """Hash of what decides clang-tidy's answer for one source."""
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
    digest = hashlib.sha256()
    for part in (config, version, json.dumps(args).encode(), out.stdout):
        digest.update(hashlib.sha256(part).digest())
    return digest.hexdigest() if out.returncode == 0 else None


def main():
    parser = argparse.ArgumentParser(usage=__doc__.split("\n\n")[1].strip())
    parser.add_argument("--all", action="store_true")
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
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
        entry = entries[path]
        key = cache_key(entry, config, version)
        marker = os.path.join(cache, key) if key else None
        if marker and os.path.exists(marker):
            return path, True, ""
        run = subprocess.run([tidy, "-p", options.build, "--quiet", path], cwd=ROOT,
                             capture_output=True, text=True)
        warnings = [line for line in run.stdout.splitlines() if ": warning: " in line
                    or ": error: " in line]
        clean = run.returncode == 0 and not warnings
        if clean and marker:
            open(marker, "w").close()
        return path, clean, run.stdout if not clean else ""

    failed, cached = [], 0
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, options.jobs)) as pool:
        for path, clean, report in pool.map(check, files):
            if not clean:
                failed.append(path)
                sys.stdout.write(report)
    if failed:
        print(f"tidy.py: clang-tidy warns in {len(failed)} of {len(files)} sources: "
              + ", ".join(failed), file=sys.stderr)
        return 1
    print(f"tidy.py: {len(files)} sources are clean by .clang-tidy")
    return 0


if __name__ == "__main__":
    sys.exit(main())
