#!/usr/bin/env python3
"""Runs the runnable code blocks of README.md and docs/*.md (ctest label `docs`).

A fenced block is runnable when the line before its opening fence (blank lines allowed in
between) is one of these HTML comments (invisible on GitHub; docs/cli.md "Runnable docs"):

  <!-- runnable -->               the block is a bash script
  <!-- runnable: console -->      a transcript: lines starting with "$ " (and their "\\"
                                  continuation lines) are run, the other lines are output
  <!-- runnable: python -->       a Python script, run with python3 and
                                  PYTHONPATH=build/tests/python/stubs:client-python
  <!-- runnable: file PATH -->    the block is written to PATH for later blocks of the page;
                                  "//" comments are removed when PATH ends in .json

Each page gets one fresh folder that looks like a clone: a copy of data/, symbolic links to
the repository's other top-level entries, `build` -> the build folder; HOME is inside it. Its
blocks run there in order with `set -euo pipefail`, PATH starting with the built `hdeform`
and `hdeform-server`. Background processes a block starts are killed when it ends. A failing
block is reported as FILE:LINE with its script and output; the exit code is 1 if any failed.

  run_docs.py --repo ROOT --build BUILD [--python PY] [--timeout S] [--list] [PAGE.md …]

--python: the interpreter the blocks get as `python3` (one with grpc and numpy, as
scripts/install-deps.sh installs for /usr/bin/python3).
  run_docs.py --self-test --build BUILD    (checks that a failing block fails the run)
"""
import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

MARKER = re.compile(r"^\s*<!--\s*runnable(?::\s*(console|python|file\s+(\S+)))?\s*-->\s*$")
FENCE = re.compile(r"^(\s*)(```+|~~~+)(.*)$")


class Block:
    def __init__(self, page, line, kind, path, text):
        self.page, self.line, self.kind, self.path, self.text = page, line, kind, path, text

    def where(self):
        return f"{self.page}:{self.line}"


def parse_page(path, shown):
    """The runnable blocks of one page; a marker without a fence after it is an error."""
    lines = open(path, encoding="utf-8").read().split("\n")
    blocks, errors = [], []
    i = 0
    while i < len(lines):
        m = MARKER.match(lines[i])
        if not m:
            i += 1
            continue
        kind = "script"
        target = None
        if m.group(1):
            kind = m.group(1) if m.group(1) in ("console", "python") else "file"
            target = m.group(2)
        j = i + 1
        while j < len(lines) and not lines[j].strip():
            j += 1
        f = FENCE.match(lines[j]) if j < len(lines) else None
        if not f:
            errors.append(f"{shown}:{i + 1}: runnable marker not followed by a fenced block")
            i += 1
            continue
        indent, fence = f.group(1), f.group(2)
        body = []
        k = j + 1
        while k < len(lines) and not (lines[k].strip().startswith(fence[0] * len(fence))
                                      and lines[k].strip().strip(fence[0]) == ""):
            body.append(lines[k][len(indent):] if lines[k].startswith(indent) else lines[k])
            k += 1
        if k >= len(lines):
            errors.append(f"{shown}:{j + 1}: unclosed fence")
            break
        blocks.append(Block(shown, j + 1, kind, target, "\n".join(body) + "\n"))
        i = k + 1
    return blocks, errors


def console_commands(text):
    """The commands of a transcript: "$ " lines and their continuation lines."""
    out, cont = [], False
    for line in text.split("\n"):
        if cont:
            out.append(line)
            cont = line.rstrip().endswith("\\")
        elif line.startswith("$ "):
            out.append(line[2:])
            cont = line.rstrip().endswith("\\")
    return "\n".join(out) + "\n"


def strip_json_comments(text):
    """Removes // comments outside JSON strings (the docs annotate their JSON examples)."""
    out, in_str, esc, i = [], False, False, 0
    while i < len(text):
        c = text[i]
        if in_str:
            out.append(c)
            esc = (c == "\\") and not esc
            if c == '"' and not esc:
                in_str = False
        elif c == '"':
            in_str = True
            out.append(c)
        elif text.startswith("//", i):
            while i < len(text) and text[i] != "\n":
                i += 1
            continue
        else:
            out.append(c)
        i += 1
    return "".join(out)


def make_clone(repo, build, folder):
    """A folder that looks like a fresh clone with a build: data/ copied (blocks may write
    into it), every other top-level entry linked, build/ -> the build folder."""
    for name in sorted(os.listdir(repo)):
        if name == ".git" or name.startswith("build"):
            continue
        src = os.path.join(repo, name)
        if name == "data":
            shutil.copytree(src, os.path.join(folder, name))
        else:
            os.symlink(src, os.path.join(folder, name))
    os.symlink(os.path.abspath(build), os.path.join(folder, "build"))
    os.makedirs(os.path.join(folder, ".home"))


def run_block(block, folder, env, timeout):
    """Runs one block in `folder`; returns (ok, output, seconds)."""
    if block.kind == "file":
        dest = os.path.join(folder, block.path)
        os.makedirs(os.path.dirname(dest) or folder, exist_ok=True)
        text = strip_json_comments(block.text) if dest.endswith(".json") else block.text
        with open(dest, "w", encoding="utf-8") as f:
            f.write(text)
        return True, f"wrote {block.path}\n", 0.0
    script = console_commands(block.text) if block.kind == "console" else block.text
    if block.kind == "python":
        with open(os.path.join(folder, ".block.py"), "w", encoding="utf-8") as f:
            f.write(block.text)
        script = ("PYTHONPATH=build/tests/python/stubs:client-python python3 .block.py\n")
    log_path = os.path.join(folder, ".block-output")
    start = time.monotonic()
    # Output to a file, not a pipe: a server the block leaves in the background would hold a
    # pipe open. Own process group: everything the block started is killed afterwards.
    with open(log_path, "w") as log:
        proc = subprocess.Popen(["bash", "-c", "set -euo pipefail\n" + script], cwd=folder,
                                env=env, stdin=subprocess.DEVNULL, stdout=log,
                                stderr=subprocess.STDOUT, start_new_session=True)
        try:
            rc = proc.wait(timeout=timeout)
            timed_out = False
        except subprocess.TimeoutExpired:
            rc, timed_out = -1, True
        try:
            os.killpg(proc.pid, signal.SIGTERM)
            time.sleep(0.05)
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()
    output = open(log_path, encoding="utf-8", errors="replace").read()
    os.unlink(log_path)
    if timed_out:
        output += f"\n(timed out after {timeout} s)\n"
    return rc == 0, output, time.monotonic() - start


def run_pages(repo, build, pages, timeout, keep=False, python=None, verbose=False):
    env = dict(os.environ)
    bins = [os.path.join(os.path.abspath(build), d) for d in ("client-cli", "server")]
    if python:
        shim = tempfile.mkdtemp(prefix="hdeform-docs-python-")
        os.symlink(os.path.abspath(python), os.path.join(shim, "python3"))
        bins.insert(0, shim)
    env["PATH"] = os.pathsep.join(bins + [env.get("PATH", "")])
    for var in ("HDEFORM_TOKEN", "HDEFORM_TLS_CA", "HDEFORM_TLS_CLIENT_CERT",
                "HDEFORM_TLS_CLIENT_KEY"):
        env.pop(var, None)
    failures, ran, errors = [], 0, []
    t0 = time.monotonic()
    for page in pages:
        shown = os.path.relpath(page, repo)
        blocks, errs = parse_page(page, shown)
        errors += errs
        if not blocks:
            continue
        folder = tempfile.mkdtemp(prefix="hdeform-docs-")
        try:
            make_clone(repo, build, folder)
            env["HOME"] = os.path.join(folder, ".home")
            for b in blocks:
                ok, output, secs = run_block(b, folder, env, timeout)
                ran += 1
                print(f"{'ok  ' if ok else 'FAIL'} {b.where()} ({b.kind}, {secs:.1f} s)", flush=True)
                if verbose and ok:
                    print(output, flush=True)
                if not ok:
                    failures.append((b, output))
                    print(f"---- {b.where()}: the block\n{b.text}---- its output\n{output}----",
                          flush=True)
        finally:
            if keep:
                print(f"(kept {folder})")
            else:
                shutil.rmtree(folder, ignore_errors=True)
    if python:
        shutil.rmtree(bins[0], ignore_errors=True)
    for e in errors:
        print(e)
    print(f"{ran} blocks run, {len(failures)} failed, {len(errors)} marker errors, "
          f"{time.monotonic() - t0:.1f} s")
    for b, _ in failures:
        print(f"{b.where()}: runnable block failed")
    return 0 if not failures and not errors else 1


def self_test(build):
    """The runner must fail (exit 1, naming FILE:LINE) when a marked block fails."""
    with tempfile.TemporaryDirectory(prefix="hdeform-docs-selftest-") as repo:
        os.makedirs(os.path.join(repo, "data"))
        page = os.path.join(repo, "page.md")
        with open(page, "w") as f:
            f.write("# t\n\n<!-- runnable -->\n```sh\ntrue\n```\n\n"
                    "<!-- runnable: console -->\n```\n$ echo hi\nhi\n$ false\n```\n"
                    "\n<!-- runnable -->\n\nno fence\n")
        r = subprocess.run([sys.executable, __file__, "--repo", repo, "--build", build, page],
                           capture_output=True, text=True)
        print(r.stdout)
        ok = (r.returncode == 1 and "page.md:9: runnable block failed" in r.stdout
              and "ok   page.md:4" in r.stdout
              and "page.md:15: runnable marker not followed by a fenced block" in r.stdout)
        print("self-test:", "ok" if ok else "FAILED")
        return 0 if ok else 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repo", default=os.path.join(os.path.dirname(__file__), "..", ".."))
    ap.add_argument("--build", required=True)
    ap.add_argument("--timeout", type=float, default=120, help="seconds per block")
    ap.add_argument("--python", help="the blocks' python3")
    ap.add_argument("--list", action="store_true", help="list the runnable blocks only")
    ap.add_argument("--keep", action="store_true", help="keep each page's folder")
    ap.add_argument("-v", "--verbose", action="store_true", help="print every block's output")
    ap.add_argument("--self-test", action="store_true")
    ap.add_argument("pages", nargs="*")
    a = ap.parse_args()
    if a.self_test:
        return self_test(a.build)
    repo = os.path.abspath(a.repo)
    pages = a.pages or ([os.path.join(repo, "README.md")] +
                        sorted(os.path.join(repo, "docs", p)
                               for p in os.listdir(os.path.join(repo, "docs")) if p.endswith(".md")) +
                        [os.path.join(repo, "data", "README.md")])
    if a.list:
        for p in pages:
            blocks, errs = parse_page(p, os.path.relpath(p, repo))
            for b in blocks:
                print(b.where(), b.kind, b.path or "")
            for e in errs:
                print(e)
        return 0
    return run_pages(repo, a.build, pages, a.timeout, a.keep, a.python, a.verbose)


if __name__ == "__main__":
    sys.exit(main())
