"""Helpers the tileset tests share (tests/tools and tests/cluster import it).

tree(root, ...): sha256 of every file under a folder, for byte-identity checks.
StepRunner: the steps of a plan.json (`decalprep build --plan N`), each run
as its command line says, and run twice to show that a step is idempotent.
blob_bytes(path): the decoded bytes of a package's blobs, read from its
header and blob table as formats/SPEC.md lays them out (not by decalprep).
"""
import hashlib
import os
import struct
import subprocess


def tree(root, skip=(), work=True):
    """{relative path: sha256} of every file under root, less the relative
    paths in `skip`. work=False also leaves out what may differ in the work
    folder between two runs of a step without changing the tileset: the
    intermediate GeoPackage (its tables carry a timestamp) and the tile
    records (they say whether a tile was built or kept)."""
    out = {}
    for d, _, files in os.walk(root):
        for f in files:
            p = os.path.join(d, f)
            rel = os.path.relpath(p, root)
            if rel in skip:
                continue
            if not work and (rel.endswith("parts.gpkg") or
                             ("/tiles/" in "/" + rel and rel.endswith(".json"))):
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
