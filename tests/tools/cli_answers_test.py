#!/usr/bin/env python3
"""What `verify`, `dump` and `render` answer where a user can slip.

  cli_answers_test.py DECALPREP REPO_ROOT WORK_DIR

On the checked-in package tests/formats/legacy/golden_v1_2.decals:
- `dump --blob nope` exits 2 and lists the package's blob names, which
  `info --json` gives (the oracle);
- `verify` of a missing path exits 3 (input), not 5 (corrupt); of a copy
  with one blob byte flipped exits 5; of both, 5;
- `verify --json` prints one object whose entries say, per path, ok or the
  reason and whether the path could not be read;
- `render -o x.jpg` (and `--decals d.tif`) exits 2 before drawing, names
  the .png to use, and leaves no file under the given name.
"""
import json
import os
import shutil
import subprocess
import sys


def run(cmd):
    return subprocess.run(cmd, capture_output=True, text=True)


def main(tool, root, work):
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    pkg = os.path.join(work, "golden.decals")
    shutil.copy(os.path.join(root, "tests", "formats", "legacy", "golden_v1_2.decals"), pkg)
    failures = []

    def expect(what, ok, detail=""):
        print(("ok   " if ok else "FAIL ") + what + ("" if ok else ": " + detail))
        if not ok:
            failures.append(what)

    info = json.loads(run([tool, "info", pkg, "--json"]).stdout)
    names = [b["name"] for b in info["blobs"]]

    r = run([tool, "dump", pkg, "--blob", "nope"])
    expect("dump --blob nope exits 2", r.returncode == 2, "exit %d" % r.returncode)
    expect("dump --blob nope lists the blob names",
           all(n in r.stderr for n in names) and "its blobs:" in r.stderr, r.stderr)

    missing = os.path.join(work, "missing.decals")
    r = run([tool, "verify", missing])
    expect("verify of a missing file exits 3 (input)", r.returncode == 3,
           "exit %d: %s" % (r.returncode, r.stderr))
    expect("verify of a missing file names it", missing in r.stderr, r.stderr)

    bad = os.path.join(work, "flipped.decals")
    data = bytearray(open(pkg, "rb").read())
    last = info["blobs"][-1]
    data[last["offset"] + last["stored_size"] // 2] ^= 0x01
    open(bad, "wb").write(data)
    r = run([tool, "verify", bad])
    expect("verify of a flipped byte exits 5", r.returncode == 5, "exit %d" % r.returncode)
    r = run([tool, "verify", bad, missing])
    expect("verify of a corrupt and a missing file exits 5", r.returncode == 5,
           "exit %d" % r.returncode)

    r = run([tool, "verify", pkg, bad, missing, "--json"])
    try:
        j = json.loads(r.stdout)
        by = {e["path"]: e for e in j["packages"]}
        expect("verify --json: one entry per path", set(by) == {pkg, bad, missing}, r.stdout)
        expect("verify --json: the good package ok with a summary",
               by[pkg]["ok"] and "blobs" in by[pkg]["summary"], r.stdout)
        expect("verify --json: the flipped one not ok, readable, with a reason",
               not by[bad]["ok"] and not by[bad]["unreadable"] and by[bad]["reason"], r.stdout)
        expect("verify --json: the missing one unreadable",
               not by[missing]["ok"] and by[missing]["unreadable"], r.stdout)
        expect("verify --json: ok false overall, exit 5", not j["ok"] and r.returncode == 5,
               "exit %d" % r.returncode)
    except (ValueError, KeyError) as e:
        expect("verify --json prints one JSON object", False, "%s: %r" % (e, r.stdout[:500]))
    r = run([tool, "verify", pkg, "--json"])
    expect("verify --json of a good package: ok true, exit 0",
           r.returncode == 0 and json.loads(r.stdout)["ok"], r.stdout + r.stderr)

    for opts, name in ((["-o", os.path.join(work, "x.jpg")], "x.jpg"),
                       (["-o", os.path.join(work, "y.png"), "--decals",
                         os.path.join(work, "d.TIF")], "d.TIF")):
        r = run([tool, "render", pkg, "--cpu", "--flat", "--size", "64x36"] + opts)
        expect("render %s exits 2" % name, r.returncode == 2, "exit %d: %s" % (r.returncode, r.stderr))
        expect("render %s names the .png to use" % name,
               os.path.splitext(name)[0] + ".png" in r.stderr, r.stderr)
        expect("render %s writes nothing" % name,
               not os.path.exists(os.path.join(work, name)) and
               not os.path.exists(os.path.join(work, "y.png")), str(os.listdir(work)))

    if failures:
        print("FAIL: %d checks" % len(failures))
        return 1
    print("PASS")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    sys.exit(main(*sys.argv[1:4]))
