#!/usr/bin/env python3
"""--max-memory is honest: a build whose source driver needs more than the
limit stops with exit 6 while its resident set is still within the limit
(plus SLACK_MIB, what the read may allocate between two polls of the
resident-set watch: prep/memory_estimate.hpp RssWatch), not after it has
passed it; a limit the build fits in still builds; and a size without a
unit is a usage error (exit 2) that suggests one.

The source is ~100 MB of GeoJSON in 10 features of ~10 MB each: GDAL's
GeoJSON driver parses each feature's JSON object whole, about 22 MiB of memory
per MB of it (bench/memory/geojson_peak_rss.csv), so reading it peaks far
above what the file's size says before the read.

  memory_test.py DECALPREP WORK_DIR SOURCE_DIR
"""
import json
import os
import random
import shutil
import subprocess
import sys
import threading

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import safety  # noqa: E402
from safety import Failure, Skip  # noqa: E402

suite = safety.Suite(sys.argv)
SLACK_MIB = 16


def write_big_features(path, features, mb_each, seed=7):
    """`features` LineStrings of about `mb_each` MB of coordinates each."""
    rng = random.Random(seed)
    per = int(mb_each * 1e6 / 24)  # "[7.1234567,43.1234567]," is 24 bytes
    with open(path, "w") as f:
        f.write('{"type":"FeatureCollection","features":[\n')
        for k in range(features):
            lat = 43.70 + 0.001 * k
            coords = ",".join(f"[{7.40 + 1e-7 * i:.7f},{lat + 1e-5 * rng.random():.7f}]" for i in range(per))
            f.write(("," if k else "") + '{"type":"Feature","properties":{"id":%d},'
                    '"geometry":{"type":"LineString","coordinates":[%s]}}\n' % (k, coords))
        f.write("]}\n")
    return path


def build(args, timeout=90):
    """(exit code, peak RSS MiB of this child, stderr); killed after `timeout` s."""
    err_path = os.path.join(suite.work, "stderr.txt")
    with open(err_path, "w+") as err:
        p = subprocess.Popen([suite.tool] + [str(a) for a in args], stdout=subprocess.DEVNULL,
                             stderr=err, stdin=subprocess.DEVNULL)
        timer = threading.Timer(timeout, p.kill)
        timer.start()
        # The child's own peak (wait4), not the maximum over every child.
        _, status, ru = os.wait4(p.pid, 0)
        timer.cancel()
        err.seek(0)
        text = err.read()
    return os.waitstatus_to_exitcode(status), ru.ru_maxrss / 1024.0, text


def big_geojson_stops_within_limit():
    d = suite.dir("big")
    if shutil.disk_usage(d).free < 400 << 20:
        raise Skip(f"{d} has less than 400 MiB free for a 100 MB GeoJSON")
    src = write_big_features(os.path.join(d, "big.geojson"), 10, 10)
    size_mib = os.path.getsize(src) / 2**20
    # 200 MiB: above the 60 MiB base plus the file's size (what a size-based
    # estimate before the read allows), far below the ~10 x 25 MiB one
    # feature's parse takes.
    limit = 200
    pkg, report = os.path.join(d, "out.decals"), os.path.join(d, "out.json")
    code, peak, err = build(["build", src, "--kind", "line", "-o", pkg, "--report", report,
                             "-q", "--max-memory", f"{limit}M"])
    print(f"     {size_mib:.0f} MiB GeoJSON, --max-memory {limit}M: exit {code}, peak RSS {peak:.1f} MiB")
    if code != 6:
        raise Failure(f"expected exit 6, got {code}: {err.strip()[-600:]}")
    if peak > limit + SLACK_MIB:
        raise Failure(f"peak RSS {peak:.1f} MiB is over --max-memory {limit} MiB + {SLACK_MIB} MiB slack: "
                      f"the build passed the limit before it stopped ({err.strip()[-400:]})")
    if os.path.exists(pkg):
        raise Failure("a package was written")
    if "--max-memory" not in err:
        raise Failure(f"the message does not name --max-memory: {err}")
    if json.load(open(report)).get("exit_code") != 6:
        raise Failure("the report does not say exit 6")


def fitting_limit_builds():
    d = suite.dir("fits")
    src = write_big_features(os.path.join(d, "small.geojson"), 2, 2)  # ~4 MB, ~110 MiB to read
    code, peak, err = build(["build", src, "--kind", "line", "--dry-run", "-q", "--max-memory", "1G"])
    print(f"     4 MB GeoJSON, --max-memory 1G, dry run: exit {code}, peak RSS {peak:.1f} MiB")
    if code != 0:
        raise Failure(f"a build well within --max-memory 1G failed with exit {code}: {err.strip()}")


def size_without_unit():
    d = suite.dir("unit")
    src = safety.write_polygons_geojson(os.path.join(d, "p.geojson"))
    r = suite.run(["build", src, "-o", os.path.join(d, "out.decals"), "--max-memory", "200"])
    suite.expect(r, 2, "200M")
    r = suite.run(["build", src, "-o", os.path.join(d, "out.decals"), "--max-memory", "2G", "-q"])
    suite.expect(r, 0)


suite.case("a 100 MB GeoJSON of large features stops with exit 6 within --max-memory",
           big_geojson_stops_within_limit)
suite.case("a limit the read fits in builds", fitting_limit_builds)
suite.case("--max-memory 200 (no unit) is exit 2 suggesting 200M", size_without_unit)
sys.exit(suite.finish())
