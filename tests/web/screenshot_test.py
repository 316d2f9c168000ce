#!/usr/bin/env python3
"""`decalprep view --screenshot` (tests/web/CMakeLists.txt, Web.Screenshot):
the protocol of prep/view.hpp with a stand-in browser (a script that only
waits, so the test plays the page), and one real frame in Chromium.

  - no Chromium ($DECALPREP_CHROMIUM=/nonexistent): exit 12, and the message
    says `apt-get install chromium`;
  - a POST of the wrong size is refused (400) and the server waits on; the
    right size is written as a PNG of that size, the browser's process group
    is stopped and its temp profile removed;
  - a POST to /__shot/error: exit 8 with the page's text; no pixels before
    --timeout: exit 8; a browser that exits early: exit 8;
  - outputs: the package itself, or a FIFO, as --screenshot or --decals is
    refused (exit 7) and left as it was;
  - a real Chromium draws a top-down frame of the Monaco sample: the PNG has
    the asked size and is not blank; --frames 3 --stats prints the warm
    frames' median, each pass's time (GPU timestamps or wall times) and
    the requests and bytes the server sent of the package. Skipped (77) only when Chromium is
    missing or cannot start.

Usage: screenshot_test.py DECALPREP REPO_ROOT WORK_DIR
"""
import os
import re
import stat
import subprocess
import sys
import time
import urllib.error
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pixel_agreement import blank, monaco_package, read_png  # noqa: E402

SKIP = 77
failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def post(port, path, body):
    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", data=body, method="POST")
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


class Shot:
    """`view --screenshot` running in the background with the stand-in browser."""

    def __init__(self, decalprep, pkg, out, extra, env):
        self.proc = subprocess.Popen([decalprep, "view", pkg, "--screenshot", out] + extra,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        line = self.proc.stdout.readline()
        self.port = int(line.split("127.0.0.1:")[1].split("/")[0]) if "127.0.0.1:" in line else None

    def finish(self):
        out, err = self.proc.communicate(timeout=60)
        return self.proc.returncode, err


def main():
    decalprep, root, work = sys.argv[1], sys.argv[2], sys.argv[3]
    pkg, error = monaco_package(decalprep, root, work)
    if error is not None:
        print("FAIL building the Monaco sample:", error)
        return 1
    view = ["--extent", "-200,-120,200,120", "--size", "40x24"]

    # No Chromium.
    env = dict(os.environ, DECALPREP_CHROMIUM="/nonexistent")
    r = subprocess.run([decalprep, "view", pkg, "--screenshot", os.path.join(work, "none.png")] + view,
                       capture_output=True, text=True, env=env)
    check(r.returncode == 12 and "apt-get install chromium" in r.stderr,
          f"no Chromium: exit {r.returncode} (12), {r.stderr.strip()!r}")
    check(not os.path.exists(os.path.join(work, "none.png")), "no Chromium: no PNG written")

    # The stand-in browser: records its pid and profile folder, then waits.
    stub = os.path.join(work, "browser.sh")
    pidfile = os.path.join(work, "browser.pid")
    with open(stub, "w") as f:
        f.write("#!/bin/sh\necho $$ \"$@\" > '%s'\nexec sleep 300\n" % pidfile)
    os.chmod(stub, 0o755)
    env = dict(os.environ, DECALPREP_CHROMIUM=stub)

    out, dec = os.path.join(work, "frame.png"), os.path.join(work, "decals.png")
    s = Shot(decalprep, pkg, out, view + ["--decals", dec], env)
    check(s.port is not None, "the screenshot prints its URL")
    for _ in range(100):
        if os.path.exists(pidfile):
            break
        time.sleep(0.05)
    words = open(pidfile).read().split()
    pid, profile = int(words[0]), next(w.split("=", 1)[1] for w in words if w.startswith("--user-data-dir="))
    check("--headless" in words and "--enable-unsafe-webgpu" in words and "--window-size=40,24" in words
          and words[-1].endswith("/?shot=1"), f"Chromium's command line: {' '.join(words[1:])}")
    with urllib.request.urlopen(f"http://127.0.0.1:{s.port}/config.json") as c:
        config = c.read().decode()
    check('"screenshot":{' in config and '"topdownExtent":[-200.0,-120.0,200.0,120.0]' in config
          and '"terrain":null' in config, f"config.json: {config[:300]}")
    st, body = post(s.port, "/__shot/frame", b"\x80" * 100)
    check(st == 400 and b"3840" in body, f"a frame of the wrong size is refused: {st} {body!r}")
    st, _ = post(s.port, "/__shot/frame", bytes(range(256)) * 15)
    check(st == 200, f"a frame of 40*24*4 bytes: {st}")
    check(s.proc.poll() is None, "waits for --decals after the frame")
    st, _ = post(s.port, "/__shot/decals", b"\x10\x20\x30\x40" * 960)
    rc, err = s.finish()
    check(rc == 0, f"pixels in: exit {rc} {err.strip()!r}")
    w, h, rows = read_png(out)
    check((w, h) == (40, 24) and rows[0][:8] == bytes(range(8)), f"frame.png: {w}x{h}, as POSTed")
    w, h, rows = read_png(dec)
    check((w, h) == (40, 24) and rows[5][:4] == b"\x10\x20\x30\x40", f"decals.png: {w}x{h}, as POSTed")
    check(not os.path.exists(f"/proc/{pid}") or open(f"/proc/{pid}/stat").read().split()[2] == "Z",
          "the browser's process group is stopped")
    check(not os.path.exists(profile), f"its temp profile {profile} is removed")

    # The page's error, a timeout, a browser that exits early.
    s = Shot(decalprep, pkg, os.path.join(work, "err.png"), view, env)
    post(s.port, "/__shot/error", b"WebGPU adapter lost: test text")
    rc, err = s.finish()
    check(rc == 8 and "test text" in err, f"page error: exit {rc} {err.strip()!r}")
    s = Shot(decalprep, pkg, os.path.join(work, "slow.png"), view + ["--timeout", "1"], env)
    rc, err = s.finish()
    check(rc == 8 and "--timeout" in err, f"timeout: exit {rc} {err.strip()!r}")
    quick = os.path.join(work, "quick.sh")
    with open(quick, "w") as f:
        f.write("#!/bin/sh\necho 'cannot open display' >&2\nexit 3\n")
    os.chmod(quick, 0o755)
    s = Shot(decalprep, pkg, os.path.join(work, "quick.png"), view, dict(env, DECALPREP_CHROMIUM=quick))
    rc, err = s.finish()
    check(rc == 8 and "exited with status 3" in err and "cannot open display" in err,
          f"browser exits early: exit {rc} {err.strip()!r}")
    check(not any(os.path.exists(os.path.join(work, n)) for n in ("err.png", "slow.png", "quick.png")),
          "no PNG after a failure")

    # Outputs: never an input, never a special file.
    before = os.stat(pkg)
    fifo = os.path.join(work, "fifo.png")
    os.mkfifo(fifo)
    for target, extra in ((pkg, []), (fifo, []), (os.path.join(work, "ok.png"), ["--decals", pkg]),
                          (os.path.join(work, "ok.png"), ["--decals", fifo])):
        r = subprocess.run([decalprep, "view", pkg, "--screenshot", target] + view + extra,
                           capture_output=True, text=True, env=env, timeout=60)
        check(r.returncode == 7, f"output {target} {extra}: exit {r.returncode} (7) {r.stderr.strip()!r}")
    after = os.stat(pkg)
    check((before.st_size, before.st_mtime_ns) == (after.st_size, after.st_mtime_ns)
          and stat.S_ISFIFO(os.stat(fifo).st_mode), "the package and the FIFO are left as they were")

    # A terrain file beside the package is what the camera is placed over:
    # a damaged one is refused before any browser starts, naming the file
    # and the field; one from another build is drawn with a warning; a FIFO
    # there is not read (flat terrain), never waited on.
    terrain = os.path.join(work, "monaco.terrain")
    t = subprocess.run([decalprep, "terrain", pkg], capture_output=True, text=True)
    check(t.returncode == 0, f"decalprep terrain: exit {t.returncode} {t.stderr.strip()!r}")
    good = open(terrain, "rb").read()
    bad = bytearray(good)
    bad[len(bad) // 2] ^= 0x40
    with open(terrain, "wb") as f:
        f.write(bad)
    other = os.path.join(work, "golden.decals")
    o = subprocess.run([decalprep, "build", os.path.join(root, "tests/tools/golden/scene.toml"), "-o", other],
                       capture_output=True, text=True)
    check(o.returncode == 0, f"building the golden scene: {o.stderr.strip()[-500:]!r}")
    with open(os.path.join(work, "golden.terrain"), "wb") as f:
        f.write(good)
    r = subprocess.run([decalprep, "view", pkg, "--screenshot", os.path.join(work, "t.png")] + view,
                       capture_output=True, text=True, env=env, timeout=60)
    check(r.returncode not in (0, 8) and "monaco.terrain" in r.stderr and "heights_checksum" in r.stderr
          and not os.path.exists(os.path.join(work, "t.png")),
          f"terrain file, damaged heights: exit {r.returncode} {r.stderr.strip()!r}")
    # Monaco's file beside the golden package (the same frame origin): a
    # file from another build is named in a warning (SPEC: source_xxh64),
    # and the view goes on (here to the missing browser, exit 12).
    r = subprocess.run([decalprep, "view", other, "--screenshot", os.path.join(work, "t.png")] + view,
                       capture_output=True, text=True, timeout=60,
                       env=dict(os.environ, DECALPREP_CHROMIUM="/nonexistent"))
    check(r.returncode == 12 and "golden.terrain was made from another build of" in r.stderr,
          f"terrain file of another build: warned, exit {r.returncode} (12) {r.stderr.strip()!r}")
    os.remove(terrain)
    os.mkfifo(terrain)
    s = Shot(decalprep, pkg, os.path.join(work, "f.png"), view, env)
    check(s.port is not None, "a FIFO named STEM.terrain is not read: the screenshot starts")
    s.proc.kill()
    s.proc.communicate(timeout=60)
    os.remove(terrain)

    # A real frame.
    real = os.path.join(work, "real.png")
    env = {k: v for k, v in os.environ.items() if k != "DECALPREP_CHROMIUM"}
    r = subprocess.run([decalprep, "view", pkg, "--screenshot", real, "--extent", "-480,-270,480,270",
                        "--size", "96x54", "--timeout", "300", "--frames", "3", "--stats"],
                       capture_output=True, text=True, env=env)
    if r.returncode == 12 or (r.returncode == 8 and "before the page sent" in r.stderr):
        print("SKIP the real frame: Chromium is missing or cannot start:", r.stderr.strip()[-1500:])
        return 1 if failures else SKIP
    check(r.returncode == 0, f"real Chromium: exit {r.returncode} {r.stderr.strip()[-2000:]!r}")
    if r.returncode == 0:
        w, h, _ = read_png(real)
        check((w, h) == (96, 54) and not blank(real), f"real.png: {w}x{h}, not blank")
        # --stats: the frame times and each pass's time (timestamps or wall).
        frame = re.search(r"^frame: ([\d.]+) ms median of 2 warm frames", r.stdout, re.M)
        passes = re.search(r"^passes \((GPU timestamps|wall time of each pass alone), median of the "
                           r"warm frames\): terrain ([\d.]+) ms, decals ([\d.]+) ms, (?:dynamic [\d.]+ ms, )?"
                           r"composite ([\d.]+) ms$",
                           r.stdout, re.M)
        check(frame is not None and passes is not None,
              f"--frames 3 --stats prints the frame and pass times: {r.stdout.strip()!r}")
        if frame and passes:
            ms = [float(passes.group(k)) for k in (2, 3, 4)]
            # The terrain and decal passes take time; the composite may be
            # 0 where the backend does it in the decal pass (WebGL2, which
            # `--backend auto` falls back to without WebGPU).
            check(ms[0] > 0 and ms[1] > 0 and ms[2] >= 0 and sum(ms) <= float(frame.group(1)) * 1.5 + 1,
                  f"pass times {ms} ({passes.group(1)}) are positive and within the frame's "
                  f"{frame.group(1)} ms")
        # --stats: what the server sent of the package (the page validates
        # every blob, so all of it, in ranged reads; no terrain file here).
        data = re.search(r"^data: (\d+) requests, (\d+) bytes of the package's files sent$", r.stdout, re.M)
        size = os.path.getsize(pkg)
        check(data is not None and int(data.group(1)) >= 2 and size <= int(data.group(2)) <= size + 4096,
              f"--stats counts the package bytes the server sent ({size} bytes in the file): "
              f"{data.group(0) if data else r.stdout.strip()!r}")
    print(f"{len(failures)} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
