"""Helpers the tileset tests share (tests/tools and tests/cluster import it).

tree(root, ...): sha256 of every file under a folder, for byte-identity checks.
StepRunner: the steps of a plan.json (`decalprep build --plan N`), each run
as its command line says, and run twice to show that a step is idempotent.
blob_bytes(path): the decoded bytes of a package's blobs, read from its
header and blob table as formats/SPEC.md lays them out (not by decalprep).
write_scene(work, layers): GeoJSON inputs in UTM 32N and a scene file over them.
plan_steps(cmd, out, n, cwd): `--plan n` for a build command line, plan.json read.
"""
import hashlib
import json
import os
import struct
import subprocess


def tree(root, skip=(), work=True):
    """{relative path: sha256} of every file under root, less the relative
    paths in `skip`. work=False also leaves out what may differ in the work
    folder between two runs of a step without changing the tileset: the
    tile records (they say whether a tile was built or kept). The parts
    file and its index are compared: they hold no timestamp."""
    out = {}
    for d, _, files in os.walk(root):
        for f in files:
            p = os.path.join(d, f)
            rel = os.path.relpath(p, root)
            if rel in skip:
                continue
            if not work and "/tiles/" in "/" + rel and rel.endswith(".json"):
                continue
            with open(p, "rb") as fh:
                out[rel] = hashlib.sha256(fh.read()).hexdigest()
    return out


def blob_bytes(path):
    """Sum of the blob table's raw_size (formats/SPEC.md "File header",
    "Blob table": the bytes a renderer uploads), read here in Python."""
    with open(path, "rb") as f:
        head = f.read(96)
        if len(head) != 96 or head[:8] != b"\x89DCL\r\n\x1a\n":
            raise ValueError("%s: not a .decals package" % path)
        header_size, entry_size, count = struct.unpack_from("<III", head, 16)
        table_offset = struct.unpack_from("<Q", head, 40)[0]
        f.seek(table_offset)
        table = f.read(entry_size * count)
    if len(table) != entry_size * count:
        raise ValueError("%s: blob table cut short" % path)
    return sum(struct.unpack_from("<Q", table, i * entry_size + 40)[0] for i in range(count))


UTM32N = {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::32632"}}


def write_scene(work, layers):
    """Writes WORK/NAME.geojson for each (name, kind, features, toml) in
    `layers` (a FeatureCollection in EPSG:32632) and WORK/scene.toml listing
    the layers in that order, each with its extra TOML lines `toml`."""
    with open(os.path.join(work, "scene.toml"), "w") as scene:
        scene.write('crs = "EPSG:32632"\n')
        for name, kind, features, toml in layers:
            with open(os.path.join(work, name + ".geojson"), "w") as f:
                json.dump({"type": "FeatureCollection", "crs": UTM32N, "features": features}, f)
            scene.write('\n[[layer]]\nname = "%s"\nsource = "%s.geojson"\nkind = "%s"\n%s'
                        % (name, name, kind, toml))


def plan_steps(cmd, out, n, cwd):
    """Runs the build command line `cmd` with `-o out --plan n -q` in `cwd`
    and returns plan.json, read; exits the test when the plan fails."""
    r = subprocess.run(cmd + ["-o", out, "--plan", str(n), "-q"], capture_output=True, text=True,
                       cwd=cwd)
    if r.returncode != 0:
        raise SystemExit("FAIL: --plan failed: " + r.stderr)
    with open(os.path.join(out, "plan.json")) as f:
        return json.load(f)


class StepRunner:
    """Runs the steps of `plan` (plan.json, read) for the tileset `out`,
    appending what went wrong to `failures`."""

    def __init__(self, plan, out, failures):
        self.steps = {s["step"]: s for s in plan["steps"]}
        self.cwd = plan["cwd"]
        self.out = out
        self.failures = failures

    def step(self, name, k=None):
        cmd = [c.replace("{K}", str(k)) for c in self.steps[name]["command"]] + ["-q"]
        return subprocess.run(cmd, capture_output=True, text=True, cwd=self.cwd)

    def run_twice(self, name, k=None, part_of=None):
        """Runs the step, then again: the second run must succeed and leave
        the bytes under `part_of` (default: the tileset) as the first left them."""
        where = part_of or self.out
        first = self.step(name, k)
        if first.returncode != 0:
            self.failures.append("%s %s failed: %s" % (name, k, first.stderr.strip()))
            return
        after_first = tree(where, skip=("plan.json",), work=False)
        second = self.step(name, k)
        if second.returncode != 0:
            self.failures.append("%s %s run again failed: %s" % (name, k, second.stderr.strip()))
        elif tree(where, skip=("plan.json",), work=False) != after_first:
            self.failures.append("%s %s run again changed the bytes" % (name, k))

    def run_all_but_last_tile_job(self, n):
        """Runs prepare and tile jobs 0 to n-2, each twice (run_twice), then
        finalize with job n-1 not run, and returns finalize's result."""
        self.run_twice("prepare", part_of=os.path.join(self.out, ".work"))
        for k in range(n - 1):
            self.run_twice("tiles", k)
        return self.step("finalize")
