#!/usr/bin/python3
"""Runs every `ptda ...` command line of the docs and of the scenario comments (issue 17 item 5).

Extracted: lines starting with `ptda <command>` or `$ ptda <command>` inside fenced code blocks of
docs/*.md and README.md (continued with a trailing backslash), and `Run: ptda ...` in the comments of
config/scenarios/*.toml. `sed`, `mkdir` and `cp` lines of the same block run too (they prepare inputs).
Not run, but counted:
  - synopsis lines: a placeholder (an upper-case token such as FILE, DIR, N), `[`, `<` or `|`;
  - blocks after a line `<!-- docs-test: skip: REASON -->` (the reason is printed; keep the list short).
A command ending in `# exit N` must exit with N, every other with 0. Each file's commands run in order
in their own scratch directory, with `config` linked to the repository's and `/tmp/` mapped into the
scratch directory. A failure names the file:line, the command, its exit status and the end of its
output. Usage: doc_commands.py --ptda BINARY --source REPO [--work DIR] [--list]
"""
import argparse
import glob
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

COMMANDS = {"simulate", "import", "doctor", "train", "monitor", "report", "evaluate", "gap", "gap-bench",
            "--help", "help"}
PREP = ("sed ", "mkdir ", "cp ")
SKIP = re.compile(r"<!--\s*docs-test:\s*skip:\s*(.*?)\s*-->")


def is_synopsis(cmd):
    if re.search(r"[\[<|]", cmd) or "..." in cmd:
        return True
    for tok in cmd.split()[1:]:
        if tok.startswith("#"):
            break
        for part in re.split(r"[/.,=:]", tok):
            if re.fullmatch(r"[A-Z][A-Z_]*", part):
                return True
    return False


def join_continued(lines, i):
    """The logical line starting at lines[i] (0-based) and the index after it."""
    text = lines[i].rstrip()
    j = i + 1
    while text.endswith("\\") and j < len(lines):
        text = text[:-1].rstrip() + " " + lines[j].strip()
        j += 1
    return text, j


def extract_markdown(path):
    """[(line, kind, text)] with kind 'run', 'prep', 'synopsis' or 'skip:<reason>'."""
    out = []
    block = 0
    lines = open(path, encoding="utf-8").read().split("\n")
    in_block = False
    skip_reason = None
    pending_skip = None
    i = 0
    while i < len(lines):
        line = lines[i]
        m = SKIP.search(line)
        if m and not in_block:
            pending_skip = m.group(1)
        if line.lstrip().startswith("```"):
            in_block = not in_block
            block += 1
            skip_reason = pending_skip if in_block else None
            if in_block:
                pending_skip = None
            i += 1
            continue
        if not in_block:
            if line.strip():
                pending_skip = pending_skip if m else None
            i += 1
            continue
        stripped = line.strip()
        if stripped.startswith("$ "):
            stripped = stripped[2:]
        words = stripped.split()
        if len(words) >= 2 and words[0] == "ptda" and words[1] in COMMANDS:
            text, j = join_continued(lines, i)
            text = text.strip()
            text = text[2:] if text.startswith("$ ") else text
            kind = ("skip:" + skip_reason) if skip_reason else ("synopsis" if is_synopsis(text) else "run")
            out.append((i + 1, kind, text, block))
            i = j
            continue
        if stripped.startswith(PREP):
            text, j = join_continued(lines, i)
            text = text.strip()
            text = text[2:] if text.startswith("$ ") else text
            out.append((i + 1, ("skip:" + skip_reason) if skip_reason else "prep", text, block))
            i = j
            continue
        i += 1
    # Preparation lines count only in blocks with a ptda command (not system setup such as /etc).
    with_ptda = {b for _, k, t, b in out if t.startswith("ptda ")}
    return [(n, k, t) for n, k, t, b in out if b in with_ptda]


def extract_scenario(path):
    out = []
    for n, line in enumerate(open(path, encoding="utf-8").read().split("\n"), 1):
        m = re.match(r"\s*#.*\bRun:\s*(ptda\s.*?)\s*$", line)
        if m:
            cmd = m.group(1)
            out.append((n, "synopsis" if is_synopsis(cmd) else "run", cmd))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ptda", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--work")
    ap.add_argument("--list", action="store_true")
    a = ap.parse_args()
    src = os.path.abspath(a.source)
    files = sorted(glob.glob(os.path.join(src, "docs", "*.md"))) + [os.path.join(src, "README.md")]
    found = []
    for f in files:
        if os.path.exists(f):
            found.append((f, extract_markdown(f)))
    for f in sorted(glob.glob(os.path.join(src, "config", "scenarios", "*.toml"))):
        found.append((f, extract_scenario(f)))
    if a.list:
        for f, cmds in found:
            for line, kind, text in cmds:
                print(f"{os.path.relpath(f, src)}:{line}: [{kind}] {text}")
        return 0

    scratch = os.environ.get("PTDA_TEST_TMP") or None
    if scratch:
        os.makedirs(scratch, exist_ok=True)
    work = a.work or tempfile.mkdtemp(prefix="ptda-docs-", dir=scratch)
    env = dict(os.environ)
    env["PATH"] = os.path.dirname(os.path.abspath(a.ptda)) + os.pathsep + env.get("PATH", "")
    failures = []
    ran = synopsis = 0
    skipped = {}
    t0 = time.monotonic()
    for f, cmds in found:
        rel = os.path.relpath(f, src)
        if not any(k in ("run", "prep") for _, k, _ in cmds):
            synopsis += sum(1 for _, k, _ in cmds if k == "synopsis")
            for line, k, text in cmds:
                if k.startswith("skip:"):
                    skipped.setdefault(k[5:], []).append(f"{rel}:{line}")
            continue
        d = os.path.join(work, re.sub(r"[^A-Za-z0-9_.-]", "_", rel))
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(os.path.join(d, "tmp"))
        os.symlink(os.path.join(src, "config"), os.path.join(d, "config"))
        for line, kind, text in cmds:
            if kind == "synopsis":
                synopsis += 1
                continue
            if kind.startswith("skip:"):
                skipped.setdefault(kind[5:], []).append(f"{rel}:{line}")
                continue
            want = 0
            m = re.search(r"#\s*exit\s+(\d+)\s*$", text)
            if m:
                want = int(m.group(1))
            cmd = re.sub(r"\s#.*$", "", text).replace("/tmp/", os.path.join(d, "tmp") + "/")
            r = subprocess.run(["bash", "-c", cmd], cwd=d, env=env, capture_output=True, text=True)
            ran += 1
            if r.returncode != want:
                tail = (r.stdout + r.stderr).strip().split("\n")[-6:]
                failures.append(f"{rel}:{line}: `{text}` exited {r.returncode} (expected {want}):\n    " +
                                "\n    ".join(tail))
    secs = time.monotonic() - t0
    print(f"docs commands: {ran} run, {synopsis} synopsis lines not run, "
          f"{sum(len(v) for v in skipped.values())} skipped by marker, {len(failures)} failed ({secs:.1f} s)")
    for reason, where in skipped.items():
        print(f"  skipped ({reason}): {', '.join(where)}")
    for fail in failures:
        print("FAILED " + fail)
    if not a.work and not failures:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
