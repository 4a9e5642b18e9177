#!/usr/bin/env python3
"""tools/mutate/mutate.py: mutation testing of the shaders (docs/VULKAN.md, "Mutation testing").

Copies the source tree (tracked and untracked-but-not-ignored files) to build/mutate/src, builds
it once (the release preset, ccache where installed), then for each mutant of tools/mutate/mutants.txt: restores
the pristine file, applies the mutant, rebuilds (-j1 by default) and runs the Catch2 tests the
mutant names (its `tests:` filter, the real-scene tests left out unless --scenes). A mutant is
  stillborn  its original text is not found exactly once, the build fails (a shader that does
             not compile), or its `tests:` filter matches no test;
  killed     the tests fail;
  timeout    the tests ran past --timeout (inconclusive on a loaded machine: not counted);
  survived   the tests pass.
Writes a table to stdout and, with --report FILE, a JSON report. Exit 0 when every non-equivalent
mutant that compiled was killed, 3 otherwise.

    python3 tools/mutate/mutate.py                  # every mutant
    python3 tools/mutate/mutate.py --only clear-barrier,shade-gap-uv -j2 --report build/mutate.json
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def parse_mutants(path):
    mutants, cur = [], None
    with open(path) as f:
        for line in f.read().splitlines():
            if line.startswith("## "):
                ident, _, desc = line[3:].partition(":")
                cur = {"id": ident.strip(), "description": desc.strip(), "file": None, "tests": "[vulkan]",
                       "original": [], "replacement": [], "equivalent": None}
                mutants.append(cur)
            elif cur is None or not line.strip() or line.startswith("#"):
                continue
            elif line.startswith("file:"):
                cur["file"] = line[5:].strip()
            elif line.startswith("tests:"):
                cur["tests"] = line[6:].strip()
            elif line.startswith("equivalent:"):
                cur["equivalent"] = line[11:].strip()
            elif line.startswith("- "):
                cur["original"].append(line[2:])
            elif line.startswith("+ "):
                cur["replacement"].append(line[2:])
            elif line.strip() == "+":
                cur["replacement"].append("")
            else:
                raise SystemExit(f"{path}: cannot read line: {line!r}")
    for m in mutants:
        if not m["file"] or not m["original"]:
            raise SystemExit(f"{path}: mutant {m['id']} lacks file: or - lines")
    return mutants


def apply(text, m):
    """The mutated text, or None when the original (lines matched with any leading blanks) is not
    found exactly once."""
    pattern = r"\n[ \t]*".join(re.escape(l.strip()) for l in m["original"])
    found = list(re.finditer(pattern, text))
    if len(found) != 1:
        return None
    s = found[0]
    line_start = text.rfind("\n", 0, s.start()) + 1
    indent = re.match(r"[ \t]*", text[line_start:]).group(0)
    repl = ("\n" + indent).join(l.strip() for l in m["replacement"])
    return text[:s.start()] + repl + text[s.end():]


def catch_filter(tests, scenes):
    """The Catch2 filter of a `tests:` line: every name pattern quoted (Catch2 2.x reads an unquoted
    name pattern up to the next tag, so `~[scenes]~*66049*` or `~*a*~*b*` excluded nothing), and
    without `scenes` the real-scene tests left out of each comma-separated part."""
    parts = []
    for part in tests.split(","):
        tokens = re.findall(r'(~?)(\[[^\]]*\]|"[^"]*"|[^~\["]+)', part.strip())
        text = "".join(neg + (tok if tok[0] in '["' else '"' + tok + '"') for neg, tok in tokens)
        parts.append(text + ("" if scenes else "~[scenes]"))
    return ",".join(parts)


def run(cmd, cwd, timeout=None, env=None):
    try:
        p = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=timeout, env=env,
                           text=True)
        return p.returncode, p.stdout
    except subprocess.TimeoutExpired as e:
        return 124, (e.stdout or b"").decode() if isinstance(e.stdout, bytes) else (e.stdout or "")


def copy_tree(dest):
    files = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                           stdout=subprocess.PIPE, check=True).stdout.decode().split("\0")
    for rel in filter(None, files):
        src = os.path.join(ROOT, rel)
        if not os.path.isfile(src) or os.path.islink(src):
            continue
        out = os.path.join(dest, rel)
        os.makedirs(os.path.dirname(out), exist_ok=True)
        if not os.path.exists(out) or open(src, "rb").read() != open(out, "rb").read():
            shutil.copy2(src, out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mutants", default=os.path.join(ROOT, "tools/mutate/mutants.txt"))
    ap.add_argument("--only", help="comma-separated mutant ids")
    ap.add_argument("--work", default=os.path.join(ROOT, "build/mutate/src"), help="the copy of the tree")
    ap.add_argument("-j", type=int, default=1, help="build jobs")
    ap.add_argument("--timeout", type=int, default=1800, help="seconds per mutant's test run")
    ap.add_argument("--scenes", action="store_true", help="also run the real-scene tests ([scenes])")
    ap.add_argument("--report", help="write a JSON report here")
    a = ap.parse_args()

    mutants = parse_mutants(a.mutants)
    if a.only:
        keep = set(a.only.split(","))
        mutants = [m for m in mutants if m["id"] in keep]
    work = os.path.abspath(a.work)
    os.makedirs(work, exist_ok=True)
    copy_tree(work)
    env = dict(os.environ)
    env.setdefault("GRIDRT_SCENES", os.path.join(os.path.dirname(ROOT), "shared", "data", "scenes"))
    if shutil.which("ccache"):  # where installed (the copy builds without it too, only slower)
        for k, v in (("CMAKE_CXX_COMPILER_LAUNCHER", "ccache"), ("CMAKE_C_COMPILER_LAUNCHER", "ccache")):
            env.setdefault(k, v)
    build = os.path.join(work, "build", "release")
    binary = os.path.join(build, "tests", "gridrt_tests")
    rc, out = run(["cmake", "--preset", "release"], work, env=env)
    if rc == 0:
        rc, out = run(["cmake", "--build", "--preset", "release", f"-j{a.j}"], work, env=env)
    if rc != 0:
        print(out[-3000:])
        raise SystemExit("the unmutated copy does not build")

    results = []
    for m in mutants:
        path = os.path.join(work, m["file"])
        pristine = open(path).read()  # the copy's own file (restored after every mutant)
        mutated = apply(pristine, m)
        t0 = time.time()
        r = {"id": m["id"], "file": m["file"], "description": m["description"], "equivalent": m["equivalent"]}
        if mutated is None:
            r.update(status="stillborn", why="original text not found exactly once")
        else:
            with open(path, "w") as f:
                f.write(mutated)
            rc, out = run(["cmake", "--build", "--preset", "release", f"-j{a.j}"], work, env=env)
            if rc != 0:
                r.update(status="stillborn", why="build failed: " + " ".join(out.strip().splitlines()[-3:])[:300])
            else:
                # --warn NoTests: a filter that matches no test fails (it would pass as a survivor)
                rc, out = run([binary, catch_filter(m["tests"], a.scenes), "--abort", "--warn", "NoTests"], work,
                              timeout=a.timeout, env=env)
                if "No tests ran" in out:
                    r.update(status="stillborn", why="the tests: filter matches no test")
                elif rc == 0:
                    r.update(status="survived")
                elif rc == 124:
                    r.update(status="timeout", why=f"tests ran past {a.timeout} s")
                else:
                    fail = re.findall(r"^(.*?) FAILED:|^-{5,}\n(.*)$", out, re.M)
                    lines = [l for l in out.splitlines() if l.strip()]
                    r.update(status="killed", why=lines[-2] if len(lines) > 1 else "")
                    # The first test whose section of the report holds a failure (a test's
                    # warnings print its name too)
                    heads = [h for h in re.finditer(r"^-{70,}\n(.+)\n", out, re.M)
                             if not re.search(r"\.\w+:\d+$", h.group(1)) and not h.group(1).startswith("-")]
                    for i, h in enumerate(heads):
                        end = heads[i + 1].start() if i + 1 < len(heads) else len(out)
                        if "FAILED" in out[h.end():end]:
                            r["by"] = h.group(1)
                            break
        with open(path, "w") as f:
            f.write(pristine)
        r["seconds"] = round(time.time() - t0, 1)
        results.append(r)
        print(f"{r['status']:10s} {m['id']:28s} {r['seconds']:7.1f} s  {r.get('by', r.get('why', ''))}", flush=True)
    # Leave the copy built as the tree is
    run(["cmake", "--build", "--preset", "release", f"-j{a.j}"], work, env=env)

    counted = [r for r in results if r["status"] in ("killed", "survived") and not r["equivalent"]]
    killed = sum(r["status"] == "killed" for r in counted)
    survivors = [r["id"] for r in counted if r["status"] == "survived"]
    print(f"\nscore: {killed} of {len(counted)} killed ({len(results) - len(counted)} stillborn, equivalent or timed out)"
          + (f"; survivors: {', '.join(survivors)}" if survivors else "")
          + "".join(f"; timeout: {r['id']}" for r in results if r["status"] == "timeout"))
    if a.report:
        tmp = a.report + ".tmp"
        with open(tmp, "w") as f:
            json.dump({"killed": killed, "counted": len(counted), "survivors": survivors, "mutants": results}, f,
                      indent=1)
        os.replace(tmp, a.report)
    return 0 if not survivors else 3


if __name__ == "__main__":
    sys.exit(main())
