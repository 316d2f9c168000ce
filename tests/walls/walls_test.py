#!/usr/bin/env python3
"""The stage walls (tests/walls/CMakeLists.txt): builds each probe target and
checks that a forbidden include fails on that very header (the compiler's
"No such file or directory" naming it) and that an allowed one compiles.

Usage: walls_test.py CMAKE BUILD_DIR walls_<name>:<header>:<allowed|forbidden>...
"""
import subprocess
import sys


def main() -> int:
    cmake, build_dir, probes = sys.argv[1], sys.argv[2], sys.argv[3:]
    failed = 0
    for probe in probes:
        target, header, kind = probe.rsplit(":", 2)
        run = subprocess.run([cmake, "--build", build_dir, "--target", target],
                             capture_output=True, text=True, timeout=600)
        out = run.stdout + run.stderr
        if kind == "allowed":
            ok = run.returncode == 0
            why = "compiles" if ok else "does not compile:\n" + out[-2000:]
        else:
            blocked = f"{header}: No such file or directory" in out
            ok = run.returncode != 0 and blocked
            why = ("refused: the header is not on its include path" if ok else
                   "was not refused for the header (exit %d):\n%s" % (run.returncode, out[-2000:]))
        print(f"{'ok  ' if ok else 'FAIL'} {target} ({kind} {header}): {why}")
        failed += not ok
    print(f"{len(probes) - failed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
