#!/usr/bin/env python3
"""Output safety: a build never destroys a file it did not create.

- a tileset build into a folder that holds other things, or whose tiles/
  is a link to another folder, refuses (exit 7) and leaves every file;
- a rebuild of a tileset removes only the tiles its index recorded;
- -o or --report naming an input, a FIFO or a device node is refused
  (exit 7) and the file stays what it was;
- two builds into one folder: the second is refused while the first holds
  the folder's lock;
- SIGINT / SIGTERM of a tileset build removes its work folder (and the
  folder itself when the build made it) and exits 130 / 143;
- inputs that are FIFOs (a source, a scene file) are refused at once.

Usage: output_test.py DECALPREP WORK_DIR [SOURCE_DIR]
"""
import fcntl
import json
import os
import signal
import stat
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from safety import Failure, Skip, Suite, snapshot, write_lines_geojson  # noqa: E402

S = Suite(sys.argv)


def lines(d, n=5):
    return write_lines_geojson(os.path.join(d, "small.geojson"), n=n)


def tileset_args(src, out, *extra, width=3, tile=500):
    return ["build", src, "-o", out, "--kind", "line", "--width", str(width), "--tile-size", str(tile),
            "-q"] + list(extra)


def expect_refused_leaving(args, folder, needle, what):
    """decalprep `args` is refused (exit 7, its message naming `needle`) and
    leaves `folder` (`what` in the failure) as it was."""
    before = snapshot(folder)
    S.expect(S.run(args), 7, needle)
    after = snapshot(folder)
    if after != before:
        raise Failure(f"{what} changed: {before} -> {after}")


def foreign_folder():
    """The audit's folder: a work folder, a manifest and tiles that are not decalprep's."""
    d = S.dir("foreign")
    src = lines(d)
    u = os.path.join(d, "u")
    for sub in (".work", "tiles/L3"):
        os.makedirs(os.path.join(u, sub))
    for f in (".work/n", "manifest.json", "tiles/xray.decals", "tiles/L3/x1_y1.decals"):
        with open(os.path.join(u, f), "w") as fh:
            fh.write("a\n")
    expect_refused_leaving(tileset_args(src, u), u, "nothing was written", "the folder")


def foreign_work_folder_in_tileset():
    d = S.dir("foreign_work")
    src = lines(d)
    u = os.path.join(d, "u")
    S.expect(S.run(tileset_args(src, u)), 0)
    os.makedirs(os.path.join(u, ".work"))
    with open(os.path.join(u, ".work", "mine.txt"), "w") as fh:
        fh.write("keep me\n")
    r = S.run(tileset_args(src, u))
    S.expect(r, 7, ".work exists and is not a decalprep work folder")
    if open(os.path.join(u, ".work", "mine.txt")).read() != "keep me\n":
        raise Failure("the user's file in .work changed")


def rebuild_keeps_unrecorded_files():
    """A tileset rebuilt with another tiling removes the tiles its index
    listed, and nothing else: a user's file in tiles/ and in a level folder
    stays."""
    d = S.dir("rebuild")
    src = lines(d, n=20)
    u = os.path.join(d, "u")
    S.expect(S.run(tileset_args(src, u, "--levels", "2")), 0)
    index = json.load(open(os.path.join(u, "tileset.json")))
    old_tiles = {t["file"] for t in index["tiles"]}
    for lv in index.get("levels", []):
        old_tiles |= {t["file"] for t in lv["tiles"]}
    mine = ["tiles/xray.decals", "tiles/x99_y99.decals", "tiles/L2/x77_y77.decals", "tiles/notes.txt"]
    for f in mine:
        with open(os.path.join(u, f), "w") as fh:
            fh.write("mine\n")
    # Another tile size and no levels: every old tile is stale.
    S.expect(S.run(["build", src, "-o", u, "--kind", "line", "--width", "3", "--tile-size", "700", "-q"]), 0)
    for f in mine:
        if not os.path.exists(os.path.join(u, f)) or open(os.path.join(u, f)).read() != "mine\n":
            raise Failure(f"{f} was removed or changed")
    new_index = json.load(open(os.path.join(u, "tileset.json")))
    new_tiles = {t["file"] for t in new_index["tiles"]}
    for f in old_tiles - new_tiles:
        if os.path.exists(os.path.join(u, f)):
            raise Failure(f"stale tile {f} of the old index was left")
    v = S.run(["verify", u])
    S.expect(v, 0)


def tiles_symlink_refused():
    d = S.dir("symlink")
    src = lines(d)
    other = os.path.join(d, "other")
    os.makedirs(other)
    for f in ("x0_y0.decals", "x1_y1.decals"):
        with open(os.path.join(other, f), "w") as fh:
            fh.write("precious\n")
    u = os.path.join(d, "u")
    S.expect(S.run(tileset_args(src, u)), 0)
    # Replace tiles/ by a link to the other folder.
    for f in os.listdir(os.path.join(u, "tiles")):
        os.remove(os.path.join(u, "tiles", f))
    os.rmdir(os.path.join(u, "tiles"))
    os.symlink(other, os.path.join(u, "tiles"))
    expect_refused_leaving(tileset_args(src, u, width=4), other, "tiles", "the linked folder")


def output_is_input():
    d = S.dir("same_file")
    src = lines(d)
    want = open(src, "rb").read()
    S.expect(S.run(["build", src, "-o", src, "--kind", "line", "--width", "3", "-q"]), 7, "is the input")
    # The same file by another spelling and through a hard link.
    os.link(src, os.path.join(d, "alias.geojson"))
    os.makedirs(os.path.join(d, "sub"))
    S.expect(S.run(["build", src, "-o", os.path.join(d, "sub", "..", "alias.geojson"), "--kind", "line",
                    "--width", "3", "-q"]), 7, "is the input")
    scene = os.path.join(d, "scene.toml")
    with open(scene, "w") as f:
        f.write('source = "small.geojson"\n\n[[layer]]\nname = "l"\nkind = "line"\nwidth = 3\n')
    scene_bytes = open(scene, "rb").read()
    S.expect(S.run(["build", scene, "-o", os.path.join(d, "out.decals"), "--report", scene, "-q"]), 7,
             "is the input")
    S.expect(S.run(["build", scene, "-o", os.path.join(d, "out.decals"), "--report",
                    os.path.join(d, "out.decals"), "-q"]), 2, "same file")
    if open(src, "rb").read() != want or open(scene, "rb").read() != scene_bytes:
        raise Failure("an input changed")
    if os.path.exists(os.path.join(d, "out.decals")):
        raise Failure("a package was written although the build was refused")


def special_targets():
    """A FIFO and a device node (made here, never /dev) as -o and --report."""
    d = S.dir("special")
    src = lines(d)
    fifo = os.path.join(d, "fifo")
    os.mkfifo(fifo)
    targets = [("FIFO", fifo)]
    node = os.path.join(d, "null_node")
    try:
        os.mknod(node, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
        targets.append(("character device", node))
    except PermissionError:
        print("  (not root: the device-node target is not tried)")
    for kind, t in targets:
        for args in (["-o", t], ["-o", os.path.join(d, "ok.decals"), "--report", t]):
            r = S.run(["build", src, "--kind", "line", "--width", "3", "-q"] + args, timeout=15)
            S.expect(r, 7, "exists and is")
            mode = os.lstat(t).st_mode
            if kind == "FIFO" and not stat.S_ISFIFO(mode) or kind != "FIFO" and not stat.S_ISCHR(mode):
                raise Failure(f"{t} is no longer a {kind}")
        r = S.run(tileset_args(src, t), timeout=15)
        S.expect(r, 7, "not a directory")


def link_targets():
    """-o and --report naming a symbolic link (to a file, or dangling): the
    link stays a link and what it points to is not created or changed."""
    d = S.dir("links")
    src = lines(d)
    victim = os.path.join(d, "victim.txt")
    with open(victim, "w") as f:
        f.write("mine\n")
    to_file = os.path.join(d, "to_file.decals")
    os.symlink(victim, to_file)
    dangling = os.path.join(d, "dangling.json")
    os.symlink(os.path.join(d, "created_through_link.json"), dangling)
    for args in (["-o", to_file], ["-o", os.path.join(d, "ok.decals"), "--report", dangling]):
        r = S.run(["build", src, "--kind", "line", "--width", "3", "-q"] + args)
        S.expect(r, 7, "symbolic link")
    if not os.path.islink(to_file) or open(victim).read() != "mine\n":
        raise Failure("the link or the file it points to changed")
    if os.path.exists(os.path.join(d, "created_through_link.json")):
        raise Failure("a file was created through a dangling link")


def render_side_files():
    """A top-down render writes NAME.png, NAME.pgw and NAME.png.aux.xml:
    a FIFO or a link at either side file stops it before it draws (exit 7,
    no PNG); with them clear, all three are written."""
    d = S.dir("render_side")
    src = lines(d)
    pkg = os.path.join(d, "l.decals")
    S.expect(S.run(["build", src, "-o", pkg, "--kind", "line", "--width", "3", "-q"]), 0)
    view = ["render", pkg, "--cpu", "--size", "64x48", "--extent", "-60,-60,60,60"]
    png = os.path.join(d, "v.png")
    os.mkfifo(os.path.join(d, "v.pgw"))
    S.expect(S.run(view + ["-o", png], timeout=15), 7, "v.pgw")
    os.remove(os.path.join(d, "v.pgw"))
    victim = os.path.join(d, "victim.txt")
    with open(victim, "w") as f:
        f.write("mine\n")
    os.symlink(victim, png + ".aux.xml")
    S.expect(S.run(view + ["-o", png], timeout=15), 7, "symbolic link")
    if os.path.exists(png) or open(victim).read() != "mine\n":
        raise Failure("the render drew or wrote through the link although a side file was refused")
    os.remove(png + ".aux.xml")
    S.expect(S.run(view + ["-o", png], timeout=30), 0)
    for f in (png, os.path.join(d, "v.pgw"), png + ".aux.xml"):
        if not os.path.isfile(f):
            raise Failure(f"{f} was not written")
    if open(png, "rb").read(8) != b"\x89PNG\r\n\x1a\n":
        raise Failure("the PNG does not start with the PNG signature")


def fifo_inputs():
    d = S.dir("fifo_inputs")
    fifo = os.path.join(d, "in.geojson")
    os.mkfifo(fifo)
    S.expect(S.run(["build", fifo, "-o", os.path.join(d, "a.decals"), "--kind", "line", "--width", "3", "-q"],
                   timeout=15), 3, "FIFO")
    scene = os.path.join(d, "scene.toml")
    with open(scene, "w") as f:
        f.write('source = "in.geojson"\n\n[[layer]]\nname = "l"\nkind = "line"\nwidth = 3\n')
    S.expect(S.run(["build", scene, "-o", os.path.join(d, "b.decals"), "-q"], timeout=15), 3, "FIFO")
    fifo_scene = os.path.join(d, "fifo.toml")
    os.mkfifo(fifo_scene)
    S.expect(S.run(["build", fifo_scene, "-o", os.path.join(d, "c.decals"), "-q"], timeout=15), 3, "FIFO")


def report_temp_name_untouched():
    """The report's temporary file is a name of the build's own: a file the
    user has at REPORT.tmp stays as it is."""
    d = S.dir("report_tmp")
    src = lines(d)
    rep = os.path.join(d, "r.json")
    with open(rep + ".tmp", "w") as f:
        f.write("mine\n")
    S.expect(S.run(["build", src, "-o", os.path.join(d, "a.decals"), "--kind", "line", "--width", "3",
                    "--report", rep, "-q"]), 0)
    if open(rep + ".tmp").read() != "mine\n":
        raise Failure(f"{rep}.tmp was overwritten")
    json.load(open(rep))


def full_disk():
    """On a full file system (a small tmpfs this test mounts) the build
    fails with exit 7, the package and report already there stay as they
    were, and no temporary file is left."""
    d = S.dir("full_disk")
    mnt = os.path.join(d, "mnt")
    os.makedirs(mnt)
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", mnt], capture_output=True, text=True)
    if r.returncode != 0:
        raise Skip(f"cannot mount a tmpfs here ({r.stderr.strip() or 'not root'})")
    try:
        small = lines(d, n=3)
        big = big_lines(d)
        pkg, rep = os.path.join(mnt, "out.decals"), os.path.join(mnt, "out.report.json")
        S.expect(S.run(["build", small, "-o", pkg, "--report", rep, "--kind", "line", "--width", "3", "-q"]), 0)
        before = snapshot(mnt)
        # Fill the rest but for 8 KiB.
        st = os.statvfs(mnt)
        free = st.f_bavail * st.f_frsize
        with open(os.path.join(mnt, "filler"), "wb") as f:
            f.write(b"\0" * max(0, free - 8192))
        before["filler"] = snapshot(mnt)["filler"]
        r = S.run(["build", big, "-o", pkg, "--report", rep, "--kind", "line", "--width", "3", "-q"], timeout=60)
        S.expect(r, 7)
        # The report is replaced by the failed build's (CI reads why), and
        # says so; everything else is as it was.
        failed = json.load(open(rep))
        if failed.get("package_written") is not False or failed.get("exit_code") != 7:
            raise Failure(f"the report does not say the build failed: {failed}")
        before[os.path.basename(rep)] = snapshot(mnt)[os.path.basename(rep)]
        after = snapshot(mnt)
        if after != before:
            raise Failure(f"the full file system changed: added {sorted(set(after) - set(before))}, "
                          f"changed {[k for k in before if after.get(k) != before[k]]}")
        r = S.run(tileset_args(big, os.path.join(mnt, "tiles")), timeout=60)
        S.expect(r, 7)
        if snapshot(mnt) != before:
            raise Failure(f"the tileset build left {sorted(set(snapshot(mnt)) - set(before))}")
    finally:
        subprocess.run(["umount", mnt], capture_output=True)


def lock_held():
    """While another build holds the folder (its flock), a build is refused
    at once and leaves the folder as it was."""
    d = S.dir("lock")
    src = lines(d)
    u = os.path.join(d, "u")
    S.expect(S.run(tileset_args(src, u)), 0)
    before = snapshot(u)
    fd = os.open(u, os.O_RDONLY | os.O_DIRECTORY)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        r = S.run(tileset_args(src, u, width=5), timeout=15)
        S.expect(r, 7, "another decalprep build")
    finally:
        os.close(fd)
    if snapshot(u) != before:
        raise Failure("the folder changed while its lock was held elsewhere")
    S.expect(S.run(tileset_args(src, u, width=5)), 0)


def big_lines(d):
    """Enough lines that a 200 m tileset build runs for seconds."""
    path = os.path.join(d, "big.geojson")
    feats = []
    k = 0
    for i in range(120):
        for j in range(120):
            x, y = 7.30 + i * 0.0012, 43.70 + j * 0.0009
            coords = [[x + t * 0.0001, y + (t % 2) * 0.0001] for t in range(12)]
            k += 1
            feats.append({"type": "Feature", "id": k, "properties": {},
                          "geometry": {"type": "LineString", "coordinates": coords}})
    with open(path, "w") as f:
        json.dump({"type": "FeatureCollection", "features": feats}, f)
    return path


def interrupted(sig, made):
    def case():
        d = S.dir(f"signal_{sig.name}_{'new' if made else 'existing'}")
        src = big_lines(d)
        u = os.path.join(d, "u")
        if not made:
            os.makedirs(u)
        p = subprocess.Popen([S.tool] + tileset_args(src, u, "--levels", "2", tile=200),
                             stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        t0 = time.time()
        # Wait until the build has a work folder with something in it.
        while time.time() - t0 < 60 and p.poll() is None:
            w = os.path.join(u, ".work")
            if os.path.isdir(w) and len(os.listdir(w)) >= 2:
                break
            time.sleep(0.02)
        if p.poll() is not None:
            raise Failure(f"the build ended (exit {p.returncode}) before it could be stopped")
        time.sleep(0.3)
        p.send_signal(sig)
        try:
            _, err = p.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            raise Failure("the build did not end within 30 s of the signal")
        want = 128 + sig.value
        if p.returncode != want:
            raise Failure(f"exit {p.returncode}, expected {want}\n{err[-2000:]}")
        if made and os.path.exists(u):
            raise Failure(f"the folder the build made is still there: {sorted(snapshot(u))[:10]}")
        if not made:
            if not os.path.isdir(u):
                raise Failure("the user's folder was removed")
            if os.path.exists(os.path.join(u, ".work")):
                raise Failure(".work was left behind")
        leftovers = [n for n in os.listdir(d) if n not in ("big.geojson", "u")]
        if leftovers:
            raise Failure(f"left beside the folder: {leftovers}")
    return case


S.case("a folder holding other files is refused and left as it was", foreign_folder)
S.case("a .work that is not decalprep's is never removed", foreign_work_folder_in_tileset)
S.case("a rebuild removes only the tiles the old index listed", rebuild_keeps_unrecorded_files)
S.case("tiles/ linked to another folder is refused, that folder untouched", tiles_symlink_refused)
S.case("-o or --report naming an input is refused", output_is_input)
S.case("-o or --report naming a FIFO or a device node is refused", special_targets)
S.case("-o or --report naming a symbolic link is refused", link_targets)
S.case("render: a FIFO or link at a world file is refused before drawing", render_side_files)
S.case("a FIFO source or scene file is refused at once", fifo_inputs)
S.case("the report's temp file never takes a user's name", report_temp_name_untouched)
S.case("a second build into a locked folder is refused", lock_held)
S.case("a full file system: exit 7, what was there stays, no temp file", full_disk)
S.case("SIGTERM removes the folder the build made", interrupted(signal.SIGTERM, True))
S.case("SIGINT removes the work folder of an existing folder", interrupted(signal.SIGINT, False))
sys.exit(S.finish())
