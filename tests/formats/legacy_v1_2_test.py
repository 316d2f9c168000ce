#!/usr/bin/env python3
"""A package of format 1.2 (tests/formats/legacy/golden_v1_2.decals: the
golden scene tests/tools/golden/scene.toml built by the last 1.2 writer)
still verifies, and draws exactly as today's 1.3 package of the same scene:
the CPU evaluator (decoding the 1.3 blobs to the 1.2 arrays) and GL (the
loader encoding the 1.2 blobs to the 1.3 layout the shaders read) give the
same static decal layer, float for float, for both files.

  legacy_v1_2_test.py DECALPREP ROOT
"""
import os
import subprocess
import sys
import tempfile


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        sys.exit("FAIL: %s exited %d: %s" % (" ".join(cmd), p.returncode, p.stderr[-2000:]))
    return p.stdout


def main():
    tool, root = sys.argv[1], sys.argv[2]
    old = os.path.join(root, "tests", "formats", "legacy", "golden_v1_2.decals")
    out = run([tool, "verify", old])
    if "(v1.2," not in out:
        sys.exit("FAIL: %s is not verified as v1.2: %s" % (old, out))
    with tempfile.TemporaryDirectory() as tmp:
        new = os.path.join(tmp, "golden.decals")
        run([tool, "build", os.path.join(root, "tests", "tools", "golden", "scene.toml"), "-o", new, "-q"])
        if "(v1.3," not in run([tool, "verify", new]):
            sys.exit("FAIL: today's build is not v1.3")
        for mode in (["--cpu"], ["--aa", "none"]):
            layers = []
            for pkg in (old, new):
                raw = os.path.join(tmp, "layer.raw")
                run([tool, "render", pkg, "--flat", "--fit", "--ortho", "--size", "320x240", "-o",
                     os.path.join(tmp, "img.png"), "--raw", raw] + mode)
                with open(raw, "rb") as f:
                    layers.append(f.read())
            if not layers[0] or layers[0] != layers[1]:
                sys.exit("FAIL: %s: the 1.2 and the 1.3 package draw different static layers (%d, %d bytes)"
                         % (" ".join(mode), len(layers[0]), len(layers[1])))
            covered = sum(1 for i in range(3, len(layers[0]), 16) if layers[0][i] != 0)
            if covered == 0:
                sys.exit("FAIL: %s: nothing drawn" % " ".join(mode))
            print("%s: 1.2 and 1.3 static layers equal (%d bytes)" % (" ".join(mode), len(layers[0])))
    print("ok")


if __name__ == "__main__":
    main()
