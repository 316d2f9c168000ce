#!/usr/bin/env python3
"""`decalprep view` (libprep/view, prep/view.hpp) as a client sees it.

Starts the server on a free port for a package and for a tileset folder and
checks, with a raw http.client client (paths sent exactly as written):
  - the package, its side files and the viewer are served, with the bytes on
    disk (the embedded viewer files equal web/'s);
  - traversal (`..`, percent-encoded `%2e%2e`, `%2f`, backslashes), hidden
    names, other files of the folder, folder listings and symbolic links
    that lead out of the served files give 404 or 403;
  - Range requests: 206 with Content-Range and the file's slice, suffix and
    open ranges, 416 with `bytes */SIZE` past the end; HEAD;
  - by default it listens on 127.0.0.1 only (`ss -ltn`, and a connection to
    the machine's other address is refused);
  - SIGTERM and SIGINT end it with 143 and 130;
  - with node and web/node_modules, the reader (web/src) opens the package
    over the server's Range answers and verifies it.
Usage: view_server_test.py DECALPREP SOURCE_DIR
"""
import http.client
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile

tool, root = sys.argv[1], sys.argv[2]
failures = []
checks = 0


def check(ok, what):
    global checks
    checks += 1
    if not ok:
        failures.append(what)
        print("FAIL:", what)


def start(path, *extra):
    proc = subprocess.Popen([tool, "view", path, "--port", "0", *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    m = re.search(r"http://([^:/]+|\[[^\]]+\]):(\d+)/", line)
    if not m:
        proc.kill()
        sys.exit("view did not print its URL: %r %s" % (line, proc.stderr.read()))
    return proc, m.group(1), int(m.group(2))


def request(port, path, method="GET", headers=None, host="127.0.0.1"):
    c = http.client.HTTPConnection(host, port, timeout=10)
    c.putrequest(method, path, skip_host=False, skip_accept_encoding=True)
    for k, v in (headers or {}).items():
        c.putheader(k, v)
    c.endheaders()
    r = c.getresponse()
    body = r.read()
    c.close()
    return r.status, dict((k.lower(), v) for k, v in r.getheaders()), body


def stop(proc, sig, want):
    proc.send_signal(sig)
    try:
        rc = proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        rc = None
    check(rc == want, "view after %s exited %s, want %d" % (signal.Signals(sig).name, rc, want))


work = tempfile.mkdtemp(prefix="view_test_")
try:
    # ------------------------------------------------------ a package --
    pkg_dir = os.path.join(work, "pkg")
    os.makedirs(pkg_dir)
    pkg = os.path.join(pkg_dir, "city.decals")
    shutil.copy(os.path.join(root, "tests/formats/legacy/golden_v1_2.decals"), pkg)
    data = open(pkg, "rb").read()
    size = len(data)
    open(os.path.join(pkg_dir, "city.report.json"), "w").write('{"ok": true}\n')
    open(os.path.join(pkg_dir, "secret.txt"), "w").write("not served\n")
    open(os.path.join(work, "outside.txt"), "w").write("outside\n")
    os.symlink(os.path.join(work, "outside.txt"), os.path.join(pkg_dir, "city.out.json"))
    os.symlink("secret.txt", os.path.join(pkg_dir, "city.secret.txt"))

    proc, host, port = start(pkg)
    check(host == "127.0.0.1", "default URL host is %s, not 127.0.0.1" % host)
    try:
        st, h, body = request(port, "/data/city.decals")
        check(st == 200 and body == data, "GET the package: %d, %d bytes" % (st, len(body)))
        check(h.get("accept-ranges") == "bytes", "Accept-Ranges: %s" % h.get("accept-ranges"))
        st, _, body = request(port, "/data/city.report.json")
        check(st == 200 and body == b'{"ok": true}\n', "side file: %d" % st)
        st, _, body = request(port, "/config.json")
        check(st == 200 and b'"url":"/data/city.decals"' in body, "config.json: %d %r" % (st, body))
        st, _, body = request(port, "/")
        check(st == 200 and b"/web/viewer/viewer.js" in body, "viewer page: %d" % st)
        for rel in ("viewer/viewer.js", "viewer/index.html", "src/package.js", "src/validate.js"):
            st, _, body = request(port, "/web/" + rel)
            check(st == 200 and body == open(os.path.join(root, "web", rel), "rb").read(),
                  "embedded web/%s differs from the file (%d)" % (rel, st))

        refused = [
            "/data/secret.txt", "/data/../pkg/secret.txt", "/data/..%2fsecret.txt",
            "/data/%2e%2e/outside.txt", "/data/%2E%2E/outside.txt", "/data/%2e%2e%2foutside.txt",
            "/data/..\\outside.txt", "/data/..%5coutside.txt", "/data/city.out.json",
            "/data/city.secret.txt", "/data/", "/data", "/data/.", "/data//etc/passwd",
            "/data/%2fetc%2fpasswd", "/data/city.decals/", "/web/../data/secret.txt",
            "/../outside.txt", "/%2e%2e/outside.txt", "/data/city.decals%00.txt",
            "/data/.%2e/outside.txt", "/data/%252e%252e/outside.txt", "/web/", "/data/pkg",
        ]
        for path in refused:
            st, _, body = request(port, path)
            check(st in (403, 404), "%s answered %d (%d bytes), want 404 or 403" % (path, st, len(body)))
            check(b"not served" not in body and b"outside" not in body, "%s leaked a file" % path)

        def ranged(spec):
            return request(port, "/data/city.decals", headers={"Range": spec})
        for spec, first, last in (("bytes=0-95", 0, 95), ("bytes=100-199", 100, 199),
                                  ("bytes=-50", size - 50, size - 1),
                                  ("bytes=%d-" % (size - 7), size - 7, size - 1),
                                  ("bytes=%d-%d" % (size - 3, size + 100), size - 3, size - 1),
                                  ("bytes=0-0", 0, 0)):
            st, h, body = ranged(spec)
            check(st == 206, "%s answered %d" % (spec, st))
            check(h.get("content-range") == "bytes %d-%d/%d" % (first, last, size),
                  "%s Content-Range %s" % (spec, h.get("content-range")))
            check(body == data[first:last + 1], "%s: %d bytes, not the file's slice" % (spec, len(body)))
        for spec in ("bytes=%d-" % size, "bytes=%d-%d" % (size + 5, size + 10)):
            st, h, body = ranged(spec)
            check(st == 416 and h.get("content-range") == "bytes */%d" % size,
                  "%s answered %d, Content-Range %s" % (spec, st, h.get("content-range")))
        st, h, body = request(port, "/data/city.decals", method="HEAD")
        check(st == 200 and body == b"" and h.get("content-length") == str(size),
              "HEAD: %d, Content-Length %s" % (st, h.get("content-length")))

        # Listening on 127.0.0.1 only.
        ss = shutil.which("ss")
        if ss:
            out = subprocess.run([ss, "-ltnH"], capture_output=True, text=True).stdout
            addrs = [l.split()[3] for l in out.splitlines() if l.split()[3].endswith(":%d" % port)]
            check(addrs == ["127.0.0.1:%d" % port], "ss -ltn shows the port on %s" % addrs)
        others = []
        try:
            others = subprocess.run(["hostname", "-I"], capture_output=True, text=True).stdout.split()
        except OSError:
            pass
        for addr in [a for a in others if ":" not in a and not a.startswith("127.")][:1]:
            s = socket.socket()
            s.settimeout(3)
            try:
                s.connect((addr, port))
                check(False, "a connection to %s:%d was accepted" % (addr, port))
            except OSError:
                pass
            finally:
                s.close()

        # The reader over the server's Range answers.
        node = shutil.which("node")
        if node and os.path.isdir(os.path.join(root, "web/node_modules/fzstd")):
            script = ("import('%s').then(async (R) => { const p = await R.openPackageUrl(process.argv[1]);"
                      " await p.validate(); console.log(p.blobs.length, p.minor); })"
                      ".catch((e) => { console.error(e.message); process.exit(1); });"
                      % os.path.join(root, "web/src/index.js"))
            r = subprocess.run([node, "-e", script, "http://127.0.0.1:%d/data/city.decals" % port],
                               capture_output=True, text=True, timeout=60)
            check(r.returncode == 0 and r.stdout.split() == ["28", "2"],
                  "the reader over HTTP: %s %s" % (r.stdout, r.stderr))
        else:
            print("note: node or web/node_modules missing; the reader-over-HTTP check is skipped")
    finally:
        stop(proc, signal.SIGTERM, 143)

    # ------------------------------------------------------ a tileset --
    ts = os.path.join(work, "ts")
    os.makedirs(os.path.join(ts, "tiles"))
    os.makedirs(os.path.join(ts, ".work"))
    open(os.path.join(ts, "tileset.json"), "w").write('{"tileset_version": "1.0"}\n')
    shutil.copy(pkg, os.path.join(ts, "tiles", "x0_y0.decals"))
    open(os.path.join(ts, ".work", "plan.json"), "w").write("work\n")
    os.symlink(os.path.join(work, "outside.txt"), os.path.join(ts, "tiles", "x1_y0.decals"))
    os.symlink("../tileset.json", os.path.join(ts, "tiles", "alias.json"))
    proc, host, port = start(ts)
    try:
        st, _, body = request(port, "/config.json")
        check(st == 200 and b'"kind":"tileset"' in body and b'/data/tileset.json' in body,
              "tileset config.json: %r" % body)
        st, _, body = request(port, "/data/tiles/x0_y0.decals", headers={"Range": "bytes=96-191"})
        check(st == 206 and body == data[96:192], "tile range: %d" % st)
        st, _, _ = request(port, "/data/tiles/alias.json")
        check(st == 200, "a link inside the tileset answered %d" % st)
        for path in ("/data/.work/plan.json", "/data/tiles", "/data/tiles/", "/data/tiles/x1_y0.decals",
                     "/data/tiles/../../outside.txt", "/data/tiles/%2e%2e/%2e%2e/outside.txt",
                     "/data/tiles\\x0_y0.decals", "/data/%2e%2e/pkg/city.decals"):
            st, _, body = request(port, path)
            check(st in (403, 404), "tileset %s answered %d" % (path, st))
    finally:
        stop(proc, signal.SIGINT, 130)

    # A bad path is an input error; a port in use a usage error.
    r = subprocess.run([tool, "view", os.path.join(pkg_dir, "secret.txt"), "--port", "0"],
                       capture_output=True, text=True, timeout=30)
    check(r.returncode == 3 and "view:" in r.stderr, "view of a text file: %d %s" % (r.returncode, r.stderr))
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(1)
    r = subprocess.run([tool, "view", pkg, "--port", str(s.getsockname()[1])],
                       capture_output=True, text=True, timeout=30)
    s.close()
    check(r.returncode == 2 and "cannot listen" in r.stderr, "port in use: %d %s" % (r.returncode, r.stderr))
finally:
    shutil.rmtree(work, ignore_errors=True)

print("%d of %d checks passed" % (checks - len(failures), checks))
sys.exit(1 if failures else 0)
