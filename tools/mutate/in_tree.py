#!/usr/bin/env python3
"""tools/mutate/in_tree.py: the mutants of tools/mutate/mutants.txt named by --only, applied one at
a time in this checkout's own release build (no copy of the tree, so no first build: for a few
mutants of a change, where mutate.py's copy would build everything once more). Each mutated file
is restored after its run, whatever happens; rebuild once afterwards. Same statuses as mutate.py.

    python3 tools/mutate/in_tree.py --only sparse-mask-bit-shifted,sparse-base-inclusive
"""
import argparse
import pathlib
import subprocess
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import mutate  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", required=True, help="comma-separated mutant ids")
    ap.add_argument("--mutants", default="tools/mutate/mutants.txt")
    ap.add_argument("-j", type=int, default=2, help="build jobs")
    args = ap.parse_args()
    ids = args.only.split(",")
    survived = 0
    for m in mutate.parse_mutants(args.mutants):
        if m["id"] not in ids:
            continue
        path = pathlib.Path(m["file"])
        pristine = path.read_text()
        mutated = mutate.apply(pristine, m)
        if mutated is None:
            print(f"{m['id']}: stillborn (original not found exactly once)", flush=True)
            continue
        path.write_text(mutated)
        try:
            b = subprocess.run(["cmake", "--build", "--preset", "release", f"-j{args.j}", "--target", "gridrt_tests"],
                               capture_output=True, text=True)
            if b.returncode != 0:
                print(f"{m['id']}: stillborn (build failed)", flush=True)
                continue
            t0 = time.time()
            r = subprocess.run(["build/release/tests/gridrt_tests", m["tests"]], capture_output=True, text=True)
            last = r.stdout.strip().splitlines()[-1] if r.stdout.strip() else ""
            status = "killed" if r.returncode != 0 else "survived"
            survived += status == "survived" and not m["equivalent"]
            print(f"{m['id']}: {status} ({time.time() - t0:.0f} s of tests: {last[:120]})", flush=True)
        finally:
            path.write_text(pristine)
    print("rebuild the pristine tree: cmake --build --preset release -j2")
    return 3 if survived else 0


if __name__ == "__main__":
    sys.exit(main())
