#!/usr/bin/env python3
"""`decalprep view --backend` (tests/web/CMakeLists.txt, Web.Backend): which
renderer the page opens, told by the --stats device line.

  - with Chromium as it is (WebGPU on): --backend auto and webgpu draw with
    WebGPU ("device: WebGPU ..."), --backend webgl2 with WebGL2;
  - with a Chromium that has no WebGPU (a wrapper that drops
    --enable-unsafe-webgpu and turns the WebGPU feature off): --backend auto
    falls back to WebGL2 and writes the frame, and
    --backend webgpu fails (exit 8) saying WebGPU is not available;
  - --backend vulkan is refused as a usage error before any browser starts.

Exit 0 when every check holds, 1 otherwise, 77 (skip) when Chromium is
missing or cannot start.

Usage: backend_test.py DECALPREP REPO_ROOT WORK_DIR
"""
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pixel_agreement import chromium as installed_chromium, monaco_package  # noqa: E402

SKIP = 77
BROWSER_EXIT = 12  # view --screenshot: no Chromium (docs/cli.md)
PAGE_FAILED = 8


def main():
    decalprep, root, work = sys.argv[1], sys.argv[2], sys.argv[3]
    pkg, error = monaco_package(decalprep, root, work)
    if error is not None:
        print("FAIL building the Monaco sample:", error)
        return 1
    chromium = installed_chromium()
    if not chromium:
        print("SKIP: no Chromium")
        return SKIP
    wrapper = os.path.join(work, "chromium-without-webgpu")
    with open(wrapper, "w") as f:
        f.write("#!/bin/sh\n# Chromium without WebGPU (tests/web/backend_test.py).\n"
                "for a in \"$@\"; do shift; [ \"$a\" = --enable-unsafe-webgpu ] || set -- \"$@\" \"$a\"; done\n"
                f"exec '{chromium}' --disable-features=WebGPU \"$@\"\n")
    os.chmod(wrapper, 0o755)

    failures = 0

    def view(backend, browser, name):
        out = os.path.join(work, f"{name}.png")
        env = dict(os.environ, DECALPREP_CHROMIUM=browser)
        r = subprocess.run([decalprep, "view", pkg, "--screenshot", out, "--extent", "-240,-135,240,135",
                            "--size", "160x90", "--backend", backend, "--stats", "--timeout", "300"],
                           capture_output=True, text=True, env=env, timeout=600)
        return r, out

    def expect(ok, what):
        nonlocal failures
        failures += not ok
        print(f"{'ok  ' if ok else 'FAIL'} {what}")

    cases = [("auto", chromium, "WebGPU"), ("webgpu", chromium, "WebGPU"), ("webgl2", chromium, "WebGL2"),
             ("auto", wrapper, "WebGL2")]
    for backend, browser, device in cases:
        where = "without WebGPU" if browser == wrapper else "as it is"
        r, out = view(backend, browser, f"{backend}-{'nowebgpu' if browser == wrapper else 'chromium'}")
        if r.returncode == BROWSER_EXIT or (r.returncode == PAGE_FAILED and "before the page sent" in r.stderr):
            print("SKIP: Chromium is missing or cannot start:", r.stderr.strip()[-1500:])
            return SKIP
        m = re.search(r"^device: (\S+) ", r.stdout, re.M)
        got = m.group(1) if m else "no device line"
        expect(r.returncode == 0 and got == device and os.path.getsize(out) > 0,
               f"--backend {backend}, Chromium {where}: {device} (got exit {r.returncode}, {got}) "
               f"{r.stderr.strip()[-500:] if r.returncode else ''}")
    r, _ = view("webgpu", wrapper, "webgpu-nowebgpu")
    expect(r.returncode == PAGE_FAILED and "WebGPU is not available" in r.stderr,
           f"--backend webgpu, Chromium without WebGPU: exit 8 saying WebGPU is not available "
           f"(got exit {r.returncode}: {r.stderr.strip()[-300:]!r})")
    r = subprocess.run([decalprep, "view", pkg, "--screenshot", os.path.join(work, "x.png"), "--backend", "vulkan"],
                       capture_output=True, text=True, timeout=60)
    expect(r.returncode != 0 and "--backend" in r.stderr and not os.path.exists(os.path.join(work, "x.png")),
           f"--backend vulkan refused (exit {r.returncode}: {r.stderr.strip()[-200:]!r})")
    print(f"{failures} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
