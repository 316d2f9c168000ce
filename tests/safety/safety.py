"""What the safety tests share: running the tool with a time limit (a hang
is a failure, not a stuck suite), recording each case, and the closing
"N passed, N failed" line.

A script builds a Suite from sys.argv (DECALPREP WORK_DIR SOURCE_DIR), runs
its cases with suite.case(name, fn) and ends with sys.exit(suite.finish()).
A case function raises Failure (or AssertionError) to fail and Skip to skip.
"""
import hashlib
import json
import os
import resource
import shutil
import stat
import subprocess
import sys
import traceback


class Failure(Exception):
    pass


class Skip(Exception):
    pass


class Result:
    def __init__(self, code, out, err, timed_out):
        self.code, self.out, self.err, self.timed_out = code, out, err, timed_out

    def __repr__(self):
        return f"exit {self.code}{' (timed out)' if self.timed_out else ''}\nstdout: {self.out[-2000:]}\nstderr: {self.err[-2000:]}"


class Suite:
    def __init__(self, argv):
        if len(argv) < 3:
            sys.exit(f"usage: {argv[0]} DECALPREP WORK_DIR [SOURCE_DIR]")
        self.tool = os.path.abspath(argv[1])
        self.work = os.path.abspath(argv[2])
        self.source = os.path.abspath(argv[3]) if len(argv) > 3 else os.path.dirname(
            os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        shutil.rmtree(self.work, ignore_errors=True)
        os.makedirs(self.work)
        self.passed, self.failed, self.skipped = [], [], []

    def dir(self, name):
        """A fresh folder of the work folder for one case."""
        d = os.path.join(self.work, name)
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        return d

    def run(self, args, timeout=20, cwd=None, mem_mb=None, env=None):
        """Runs the tool (args without it); a run past `timeout` seconds is
        killed and reported as timed out (exit None)."""
        def limit():
            if mem_mb:
                resource.setrlimit(resource.RLIMIT_AS, (mem_mb << 20, mem_mb << 20))
        try:
            p = subprocess.run([self.tool] + [str(a) for a in args], capture_output=True, text=True,
                               timeout=timeout, cwd=cwd, preexec_fn=limit, env=env,
                               stdin=subprocess.DEVNULL)
            return Result(p.returncode, p.stdout, p.stderr, False)
        except subprocess.TimeoutExpired as e:
            out = e.stdout.decode() if isinstance(e.stdout, bytes) else (e.stdout or "")
            err = e.stderr.decode() if isinstance(e.stderr, bytes) else (e.stderr or "")
            return Result(None, out, err, True)

    def expect(self, r, code, *needles):
        """Fails unless r exited with `code` and its stderr (or stdout)
        holds every needle."""
        if r.timed_out:
            raise Failure(f"hung (killed after the time limit); expected exit {code}\n{r}")
        if r.code != code:
            raise Failure(f"expected exit {code}\n{r}")
        text = r.err + r.out
        for n in needles:
            if n not in text:
                raise Failure(f"output lacks {n!r}\n{r}")

    def case(self, name, fn):
        try:
            fn()
        except Skip as s:
            print(f"[ SKIP ] {name}: {s}")
            self.skipped.append(name)
            return
        except (Failure, AssertionError) as f:
            print(f"[ FAIL ] {name}: {f}")
            self.failed.append(name)
            return
        except Exception:  # a bug in the case itself counts as a failure
            print(f"[ FAIL ] {name}: {traceback.format_exc()}")
            self.failed.append(name)
            return
        print(f"[  OK  ] {name}")
        self.passed.append(name)

    def finish(self):
        for n in self.failed:
            print(f"failed: {n}")
        print(f"{len(self.passed)} passed, {len(self.failed)} failed, {len(self.skipped)} skipped")
        if self.failed:
            return 1
        if not self.passed and self.skipped:
            return 77
        return 0


def snapshot(root, mtimes=False):
    """Every path below root (links not followed) -> (kind, what it holds,
    mtime): the kind as `ls -l` writes it (d, -, l, p, c...), the SHA-1 of
    a regular file's bytes or a link's target (None for the rest), and the
    modification time in ns with mtimes=True (else None). Two snapshots are
    equal when nothing below root was added, removed, rewritten, relinked
    or (with mtimes) touched."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for n in dirnames + filenames:
            p = os.path.join(dirpath, n)
            st = os.lstat(p)
            held = None
            if stat.S_ISREG(st.st_mode):
                with open(p, "rb") as f:
                    held = hashlib.sha1(f.read()).hexdigest()
            elif stat.S_ISLNK(st.st_mode):
                held = os.readlink(p)
            out[os.path.relpath(p, root)] = (stat.filemode(st.st_mode)[0], held,
                                             st.st_mtime_ns if mtimes else None)
    return out


def write_lines_geojson(path, n=3, lon=7.42, lat=43.73, step=1e-3):
    """n short lines near Monaco, a real GeoJSON file for GDAL to read."""
    feats = []
    for k in range(n):
        y = lat + k * step
        feats.append({"type": "Feature", "id": k + 1, "properties": {"k": k},
                      "geometry": {"type": "LineString", "coordinates": [[lon, y], [lon + step, y + step / 3]]}})
    with open(path, "w") as f:
        json.dump({"type": "FeatureCollection", "features": feats}, f)
    return path


def write_polygons_geojson(path, n=3, lon=7.42, lat=43.73, d=1e-3):
    """n small squares near Monaco."""
    feats = []
    for k in range(n):
        x = lon + 2 * k * d
        ring = [[x, lat], [x + d, lat], [x + d, lat + d], [x, lat + d], [x, lat]]
        feats.append({"type": "Feature", "id": k + 1, "properties": {"k": k},
                      "geometry": {"type": "Polygon", "coordinates": [ring]}})
    with open(path, "w") as f:
        json.dump({"type": "FeatureCollection", "features": feats}, f)
    return path
