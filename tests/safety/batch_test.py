#!/usr/bin/env python3
"""Batch mode and the Slurm scripts under signals, odd paths and odd numbers.

- A scene killed by a signal is named in summary.json ("signal", "killed by
  SIGKILL") and the batch exits 11, not 128 + the signal.
- SIGTERM / SIGINT to the batch reach its scenes: none survives it, the
  summary names every scene (the unfinished ones "interrupted") and the
  batch exits 143 / 130. A batch killed outright takes its scenes with it.
- The output folder: an -o that is not a folder, and a package, report, log
  or summary name that is a FIFO, a folder or an input, are refused (exit 7)
  with nothing written; other files in the folder are left as they were.
- scripts/slurm/submit: the job scripts it hands to sbatch, run by /bin/sh,
  give decalprep exactly the argv meant, whatever bytes the paths hold
  (spaces, quotes, UTF-8 under LC_ALL=C, '%', a newline); sbatch's own
  '%' patterns in log names are escaped; N=08 is 8. A stub sbatch records
  what submit asks, so no Slurm is needed.
- scripts/slurm/cluster: `stop` kills only the daemons it started, not
  whatever process now has a recorded pid; `start` passes the state folder
  to su as one word.

Usage: batch_test.py DECALPREP WORK_DIR SOURCE_DIR
(SUBMIT_UNDER_TEST / CLUSTER_UNDER_TEST name other copies of the scripts,
e.g. an older version to see these cases fail.)
"""
import json
import os
import signal
import stat
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from safety import Failure, Skip, Suite, snapshot, write_polygons_geojson  # noqa: E402

suite = Suite(sys.argv)
TOOL = suite.tool
SUBMIT = os.environ.get("SUBMIT_UNDER_TEST") or os.path.join(suite.source, "scripts", "slurm", "submit")
CLUSTER = os.environ.get("CLUSTER_UNDER_TEST") or os.path.join(suite.source, "scripts", "slurm",
                                                                "cluster")

# One source large enough that a scene takes a few seconds (about 5 s on an
# idle core), shared by the scenes that must still be running when the test
# sends its signal and until it looks for survivors.
BIG = os.path.join(suite.work, "big.geojson")
write_polygons_geojson(BIG, n=150000, d=1e-5)
SMALL = os.path.join(suite.work, "small.geojson")
write_polygons_geojson(SMALL, n=3)


def scene(folder, name, source):
    path = os.path.join(folder, name + ".toml")
    with open(path, "w") as f:
        f.write(f'source = "{source}"\n\n[[layer]]\nname = "squares"\nkind = "polygon"\n')
    return path


def children(pid):
    """The pids of pid's children (every thread's), [] once it is gone."""
    kids = []
    try:
        for tid in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{tid}/children") as f:
                kids += [int(k) for k in f.read().split()]
    except OSError:
        pass
    return kids


def alive(pid):
    """True while pid is a process that is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def start_batch(args):
    """The tool in a session of its own, so that a failed case can kill
    everything it left (scenes of an old batch outlive it)."""
    return subprocess.Popen([TOOL] + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, text=True, start_new_session=True)


def finish(p, timeout):
    """Waits for p; kills its whole session on a timeout. Returns (code,
    stderr), code None when it hung."""
    try:
        out, err = p.communicate(timeout=timeout)
        return p.returncode, err + out
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, err = p.communicate()
        return None, err + out


def kill_session(p):
    try:
        os.killpg(p.pid, signal.SIGKILL)
    except OSError:
        pass


def run_batch(args, timeout):
    """start_batch, then finish: (code, stderr); its session killed after."""
    p = start_batch(args)
    try:
        return finish(p, timeout)
    finally:
        kill_session(p)


def wait_children(pid, n, timeout=30):
    """Waits until pid has at least n children; returns them."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        kids = children(pid)
        if len(kids) >= n:
            return kids
        time.sleep(0.02)
    raise Failure(f"the batch never had {n} scene processes running")


def load_summary(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        raise Failure(f"summary {path} is not valid JSON: {e}")


# --------------------------------------------------------------- signals --

def killed_scene():
    d = suite.dir("killed")
    scenes = os.path.join(d, "scenes")
    os.makedirs(scenes)
    scene(scenes, "a_slow", BIG)
    scene(scenes, "b_small", SMALL)
    out = os.path.join(d, "out")
    p = start_batch(["build", scenes, "-o", out, "--jobs", "1"])
    try:
        kid = wait_children(p.pid, 1)[0]
        time.sleep(0.3)
        os.kill(kid, signal.SIGKILL)
        code, err = finish(p, 120)
    finally:
        kill_session(p)
    if code != 11:
        raise Failure(f"a scene killed by SIGKILL: batch exit {code}, expected 11\n{err}")
    s = load_summary(os.path.join(out, "summary.json"))
    by = {os.path.basename(e["scene"]): e for e in s["packages"]}
    a = by.get("a_slow.toml", {})
    if a.get("status") != "failed" or a.get("signal") != "SIGKILL" or \
            not a.get("error", "").startswith("killed by SIGKILL"):
        raise Failure(f"the killed scene's entry: {a}")
    if by.get("b_small.toml", {}).get("status") != "built":
        raise Failure(f"the other scene did not build: {by.get('b_small.toml')}")


def stop_batch(sig, code_expected):
    def case():
        d = suite.dir(f"stop_{signal.Signals(sig).name}")
        scenes = os.path.join(d, "scenes")
        os.makedirs(scenes)
        names = [f"s{k}" for k in range(4)]
        for n in names:
            scene(scenes, n, BIG)
        out = os.path.join(d, "out")
        p = start_batch(["build", scenes, "-o", out, "--jobs", "2"])
        try:
            kids = wait_children(p.pid, 2)
            time.sleep(0.3)
            os.kill(p.pid, sig)
            end = time.monotonic() + 2
            while time.monotonic() < end and any(alive(k) for k in kids):
                time.sleep(0.05)
            survivors = [k for k in kids if alive(k)]
            code, err = finish(p, 20)
        finally:
            kill_session(p)
        if survivors:
            raise Failure(f"scene processes {survivors} still run 2 s after "
                          f"{signal.Signals(sig).name} to the batch")
        if code != code_expected:
            raise Failure(f"batch exit {code}, expected {code_expected}\n{err}")
        s = load_summary(os.path.join(out, "summary.json"))
        got = sorted(os.path.basename(e["scene"]) for e in s.get("packages", []))
        if got != sorted(n + ".toml" for n in names):
            raise Failure(f"the summary names {got}")
        statuses = {os.path.basename(e["scene"]): e["status"] for e in s["packages"]}
        if "interrupted" not in statuses.values() or \
                any(v not in ("interrupted", "built") for v in statuses.values()):
            raise Failure(f"statuses after the stop: {statuses}")
        for n in names:
            if os.path.exists(os.path.join(out, n + ".decals")) and statuses[n + ".toml"] != "built":
                raise Failure(f"{n}.decals exists but the scene is {statuses[n + '.toml']}")
        left = [f for f in os.listdir(out) if ".tmp" in f or f.startswith(".")]
        if left:
            raise Failure(f"temp files left in the output folder: {left}")
    return case


def batch_killed_outright():
    d = suite.dir("sigkill_batch")
    scenes = os.path.join(d, "scenes")
    os.makedirs(scenes)
    for k in range(3):
        scene(scenes, f"s{k}", BIG)
    out = os.path.join(d, "out")
    p = start_batch(["build", scenes, "-o", out, "--jobs", "2"])
    try:
        kids = wait_children(p.pid, 2)
        time.sleep(0.3)
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
        end = time.monotonic() + 2
        while time.monotonic() < end and any(alive(k) for k in kids):
            time.sleep(0.05)
        survivors = [k for k in kids if alive(k)]
    finally:
        kill_session(p)
    if survivors:
        raise Failure(f"scene processes {survivors} outlived the batch killed by SIGKILL")
    s = load_summary(os.path.join(out, "summary.json"))
    got = sorted(os.path.basename(e["scene"]) for e in s.get("packages", []))
    if got != [f"s{k}.toml" for k in range(3)] or s.get("state") != "running":
        raise Failure(f"the summary of a batch killed while running: {s}")


# ---------------------------------------------------------- output folder --

def refused(setup, needle):
    """A batch of scenes a and b into out/, after setup(d, out, sources)
    planted something; it must exit 7 naming `needle`, write nothing and
    leave every file (the inputs included) as it was."""
    def case():
        d = suite.dir("out_" + setup.__name__)
        scenes = os.path.join(d, "scenes")
        os.makedirs(scenes)
        src = {k: write_polygons_geojson(os.path.join(d, f"{k}.geojson")) for k in "ab"}
        for k in "ab":
            scene(scenes, k, src[k])
        out = os.path.join(d, "out")
        args = setup(d, out, src) or []
        before = snapshot(d, mtimes=True)
        code, err = run_batch(["build", scenes, "-o", out] + args, 30)
        if code != 7:
            raise Failure(f"exit {code}, expected 7\n{err}")
        if needle not in err:
            raise Failure(f"the message lacks {needle!r}: {err}")
        after = snapshot(d, mtimes=True)
        if after != before:
            changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
            raise Failure(f"a refused batch changed {changed}")
    return case


def out_is_a_file(d, out, src):
    with open(out, "w") as f:
        f.write("not a folder\n")


def out_is_a_fifo(d, out, src):
    os.mkfifo(out)


def log_is_a_fifo(d, out, src):
    os.makedirs(out)
    os.mkfifo(os.path.join(out, "a.log"))


def package_is_a_device(d, out, src):
    os.makedirs(out)
    try:
        os.mknod(os.path.join(out, "b.decals"), 0o600 | stat.S_IFCHR, os.makedev(1, 3))
    except PermissionError:
        raise Skip("mknod needs root")


def log_is_the_source(d, out, src):
    os.makedirs(out)
    os.link(src["b"], os.path.join(out, "b.log"))


def report_is_the_scene(d, out, src):
    os.makedirs(out)
    os.symlink(os.path.join(d, "scenes", "a.toml"), os.path.join(out, "a.report.json"))


def summary_is_a_folder(d, out, src):
    os.makedirs(os.path.join(out, "summary.json"))


def other_files_left_alone():
    d = suite.dir("out_others")
    scenes = os.path.join(d, "scenes")
    os.makedirs(scenes)
    src = write_polygons_geojson(os.path.join(d, "a.geojson"))
    scene(scenes, "a", src)
    out = os.path.join(d, "out")
    os.makedirs(out)
    planted = {"notes.txt": b"mine\n", "a.decals.old": b"old\n", "summary.json.tmp": b"x\n",
               ".summary.json.tmp": b"y\n", "b.log": b"another batch's\n"}
    for n, data in planted.items():
        with open(os.path.join(out, n), "wb") as f:
            f.write(data)
    before = snapshot(out, mtimes=True)
    code, err = run_batch(["build", scenes, "-o", out], 60)
    if code != 0:
        raise Failure(f"exit {code}\n{err}")
    after = snapshot(out, mtimes=True)
    for n in planted:
        if after.get(n) != before[n]:
            raise Failure(f"the batch changed {n}")
    new = sorted(set(after) - set(before))
    if new != ["a.decals", "a.log", "a.report.json", "summary.json"]:
        raise Failure(f"the batch wrote {new}")


# ---------------------------------------------------------- slurm/submit --

# sbatch, as far as submit uses it: records each call (argv as bytes, and
# the job script: the --wrap command as sbatch's own "#!/bin/sh" wrapper, or
# the script file) and prints a job id.
STUB_SBATCH = r'''#!/usr/bin/env python3
import json, os, sys
args = [os.fsencode(a) for a in sys.argv[1:]]
log = os.environ["STUB_SBATCH_LOG"]
n = sum(1 for _ in open(log)) if os.path.exists(log) else 0
script = None
i = 0
while i < len(args):
    a = args[i]
    if a == b"--wrap":
        script = b"#!/bin/sh\n# This script was created by sbatch --wrap.\n\n" + args[i + 1] + b"\n"
        i += 2
    elif a in (b"-J", b"-o", b"-e", b"-p", b"-A"):
        i += 2
    elif a.startswith(b"-"):
        i += 1
    else:
        with open(a, "rb") as f:
            script = f.read()
        break
with open(log, "a") as f:
    f.write(json.dumps({"argv": [x.hex() for x in args], "script": script.hex()}) + "\n")
print(1000 + n)
'''

# decalprep, as far as the job scripts run it: writes its argv ($0, the
# path it was run by, first), NUL-ended.
STUB_TOOL = '#!/bin/sh\nfor a in "$0" "$@"; do printf \'%s\\0\' "$a"; done >>"$STUB_ARGV"\n'

ODD = "odd 'q' \"dq\" $HOME `x` \\b %j %% é\nline2"


def write_exe(path, text):
    with open(path, "w") as f:
        f.write(text)
    os.chmod(path, 0o755)


def submit_env(d):
    bin_dir = os.path.join(d, "bin")
    os.makedirs(bin_dir, exist_ok=True)
    write_exe(os.path.join(bin_dir, "sbatch"), STUB_SBATCH)
    env = dict(os.environ, LC_ALL="C", PATH=bin_dir + ":" + os.environ["PATH"],
               STUB_SBATCH_LOG=os.path.join(d, "sbatch.log"),
               STUB_ARGV=os.path.join(d, "argv"))
    env.pop("LANG", None)
    env.pop("DECALPREP_SUBMIT_DRY", None)
    return env


def run_job(script, env, task=None):
    """Runs a recorded job script with /bin/sh (dash here); returns the
    argv the stub decalprep got."""
    argv_file = env["STUB_ARGV"]
    if os.path.exists(argv_file):
        os.remove(argv_file)
    path = argv_file + ".job"
    with open(path, "wb") as f:
        f.write(script)
    job_env = dict(env)
    if task is not None:
        job_env["SLURM_ARRAY_TASK_ID"] = str(task)
    r = subprocess.run(["/bin/sh", path], env=job_env, capture_output=True, timeout=20)
    if r.returncode != 0 or not os.path.exists(argv_file):
        raise Failure(f"the job script failed under /bin/sh: {r.stderr!r}\n{script!r}")
    with open(argv_file, "rb") as f:
        return f.read().split(b"\0")[:-1]


def sbatch_output_name(pattern, job):
    """What sbatch makes of an --output pattern (man sbatch, "filename
    pattern"): %% is %, %j and %A the job id, %a the task id; a backslash
    anywhere turns the replacements off."""
    if b"\\" in pattern:
        return pattern.replace(b"\\", b"")
    out, i = b"", 0
    while i < len(pattern):
        c = pattern[i:i + 1]
        if c == b"%" and i + 1 < len(pattern):
            nxt = pattern[i + 1:i + 2]
            out += {b"%": b"%", b"j": job, b"A": job, b"a": b"0"}.get(nxt, b"%" + nxt)
            i += 2
        else:
            out += c
            i += 1
    return out


def stub_submit_inputs(folder, scene_name="scene.toml", tool_name="decalprep"):
    """A scene file that submit does not read and the stub decalprep, in
    folder; returns their paths."""
    scene_path, tool = os.path.join(folder, scene_name), os.path.join(folder, tool_name)
    with open(scene_path, "w") as f:
        f.write("# not read\n")
    write_exe(tool, STUB_TOOL)
    return scene_path, tool


def submit(env, tool, scene_path, out_dir, n, opts=(), text=False):
    """scripts/slurm/submit --tool TOOL SCENE OUT N [OPTS...] under env."""
    return subprocess.run(["bash", SUBMIT, "--tool", tool, scene_path, out_dir, n, *opts],
                          env=env, capture_output=True, text=text, timeout=60)


def sbatch_calls(env):
    """What the stub sbatch recorded, one dict per call."""
    with open(env["STUB_SBATCH_LOG"]) as f:
        return [json.loads(line) for line in f]


def submit_odd_paths():
    d = suite.dir("submit_odd")
    env = submit_env(d)
    base = os.path.join(d, ODD)
    os.makedirs(base)
    scene_path, tool = stub_submit_inputs(base, "scène %a.toml", "decal prep")
    out_dir = os.path.join(base, "tiles 100%")
    opts = ["--tile-size", "500", "--note", "a'b \"c\" $d `e` %j é\nf"]
    r = submit(env, tool, scene_path, out_dir, "3", opts)
    if r.returncode != 0:
        raise Failure(f"submit exit {r.returncode}: {r.stderr!r}")
    calls = sbatch_calls(env)
    if len(calls) != 3:
        raise Failure(f"{len(calls)} sbatch calls, expected 3 (prepare, tiles, finalize)")
    enc = os.fsencode
    want = [enc(tool), b"build", enc(scene_path), b"-o", enc(out_dir)] + [enc(o) for o in opts]
    steps = [[b"--step", b"prepare"], [b"--step", b"tiles", b"2/3"], [b"--step", b"finalize"]]
    logs = enc(out_dir) + b".slurm-logs"
    for k, call in enumerate(calls):
        got = run_job(bytes.fromhex(call["script"]), env, task=2)
        if got != want + steps[k]:
            raise Failure(f"job {k} ran decalprep with\n{got}\nnot\n{want + steps[k]}")
        argv = [bytes.fromhex(a) for a in call["argv"]]
        pattern = argv[argv.index(b"-o") + 1]
        name = sbatch_output_name(pattern, b"77")
        if not name.startswith(b"/"):
            # Relative to the job's --chdir (sbatch's own cwd, else).
            cwd = [a[len(b"--chdir="):] for a in argv if a.startswith(b"--chdir=")]
            if not cwd:
                raise Failure(f"job {k}: a relative -o {pattern!r} and no --chdir")
            name = os.path.join(cwd[-1], name)
        if os.path.dirname(name) != logs:
            raise Failure(f"job {k}: sbatch would write its log to {name!r}, not in {logs!r}")


def submit_n_leading_zero():
    d = suite.dir("submit_08")
    env = submit_env(d)
    scene_path, tool = stub_submit_inputs(d)
    r = submit(env, tool, scene_path, os.path.join(d, "out"), "08")
    if r.returncode != 0:
        raise Failure(f"N=08: submit exit {r.returncode}: {r.stderr!r}")
    calls = sbatch_calls(env)
    tiles = [bytes.fromhex(a) for a in calls[1]["argv"]]
    if b"--array=0-7" not in tiles:
        raise Failure(f"N=08: the tiles job is {tiles}")
    got = run_job(bytes.fromhex(calls[1]["script"]), env, task=5)
    if got[-3:] != [b"--step", b"tiles", b"5/8"]:
        raise Failure(f"N=08: task 5 ran {got}")
    for bad in ("0", "00", "-1", "1e3", "0x10", "9999999999"):
        r = submit(env, tool, scene_path, os.path.join(d, "out"), bad, text=True)
        if r.returncode != 2 or "N must be" not in r.stderr:
            raise Failure(f"N={bad}: exit {r.returncode} {r.stderr!r}")


def submit_dry_run():
    d = suite.dir("submit_dry")
    env = submit_env(d)
    env["DECALPREP_SUBMIT_DRY"] = "1"
    scene_path, tool = stub_submit_inputs(d)
    r = submit(env, tool, scene_path, os.path.join(d, "out"), "2")
    if r.returncode != 0:
        raise Failure(f"dry run: exit {r.returncode}: {r.stderr!r}")
    if os.path.exists(env["STUB_SBATCH_LOG"]):
        raise Failure("a dry run called sbatch")
    scripts = [line.split(b": ", 1)[1] for line in r.stdout.splitlines() if line.startswith(b"job script")]
    if len(scripts) != 3:
        raise Failure(f"a dry run printed {r.stdout!r}")
    with open(scripts[1], "rb") as f:
        got = run_job(f.read(), env, task=1)
    if got[-3:] != [b"--step", b"tiles", b"1/2"]:
        raise Failure(f"the dry run's tiles script ran {got}")


# --------------------------------------------------------- slurm/cluster --

def cluster_stop_checks_pids():
    d = suite.dir("cluster_stop")
    state = os.path.join(d, "state")
    os.makedirs(os.path.join(state, "munge"))
    sleeper = subprocess.Popen(["sleep", "1000"])
    try:
        for p in ("slurmd.pid", "slurmctld.pid", "munge/munged.pid"):
            with open(os.path.join(state, p), "w") as f:
                f.write(f"{sleeper.pid}\n")
        r = subprocess.run(["bash", CLUSTER, "stop"], env=dict(os.environ, DECALPREP_SLURM_DIR=state),
                           capture_output=True, text=True, timeout=60)
        time.sleep(0.2)
        if sleeper.poll() is not None:
            raise Failure(f"cluster stop killed pid {sleeper.pid}, a sleep it never started\n{r.stderr}")
        if str(sleeper.pid) not in r.stderr:
            raise Failure(f"cluster stop did not say it left pid {sleeper.pid}: {r.stderr!r}")
    finally:
        sleeper.kill()
        sleeper.wait()


def cluster_start_quotes_state():
    if os.geteuid() != 0:
        raise Skip("cluster start needs root")
    missing = [t for t in ("munged", "mungekey", "slurmctld", "slurmd", "sbatch", "sinfo")
               if not any(os.path.exists(os.path.join(p, t)) for p in
                          os.environ["PATH"].split(":") + ["/usr/sbin"])]
    if missing:
        raise Skip("not installed: " + " ".join(missing))
    d = suite.dir("cluster_start")
    # munged runs as the munge user: the folder must be reachable by it.
    os.chmod(d, 0o755)
    state = os.path.join(d, "st 'a' \"b\" $c é")
    bin_dir = os.path.join(d, "bin")
    os.makedirs(bin_dir)
    # su, recording its -c command instead of running it.
    write_exe(os.path.join(bin_dir, "su"),
              '#!/bin/sh\nwhile [ $# -gt 0 ]; do [ "$1" = -c ] && printf %s "$2" >"$SU_CMD"; shift; done\n')
    env = dict(os.environ, DECALPREP_SLURM_DIR=state, PATH=bin_dir + ":" + os.environ["PATH"],
               SU_CMD=os.path.join(d, "su.cmd"), DECALPREP_SLURM_PORT="16857")
    subprocess.run(["bash", CLUSTER, "start"], env=env, capture_output=True, timeout=60)
    subprocess.run(["bash", CLUSTER, "stop"], env=env, capture_output=True, timeout=60)
    if not os.path.exists(env["SU_CMD"]):
        raise Failure("cluster start never ran su")
    cmd = open(env["SU_CMD"]).read()
    munged = "/usr/sbin/munged"
    at = cmd.find(munged)
    if at < 0:
        raise Failure(f"su -c {cmd!r} does not run {munged}")
    # What /bin/sh makes of the command, with munged replaced by a printer.
    argv_file = os.path.join(d, "argv")
    printer = os.path.join(bin_dir, "print-argv")
    write_exe(printer, STUB_TOOL)
    shown = cmd[:at] + printer + cmd[at + len(munged):]
    subprocess.run(["/bin/sh", "-c", shown], env=dict(env, STUB_ARGV=argv_file), timeout=20)
    args = open(argv_file, "rb").read().split(b"\0")[1:-1] if os.path.exists(argv_file) else []
    want = os.fsencode("--key-file=" + os.path.join(state, "munge-key", "munge.key"))
    if want not in args:
        raise Failure(f"munged would get {args}, not {want!r}")


suite.case("a scene killed by SIGKILL: signal in summary.json, exit 11", killed_scene)
suite.case("SIGTERM to the batch: scenes stop, summary names all, exit 143",
           stop_batch(signal.SIGTERM, 143))
suite.case("SIGINT to the batch: scenes stop, summary names all, exit 130",
           stop_batch(signal.SIGINT, 130))
suite.case("SIGKILL to the batch: no scene survives it", batch_killed_outright)
suite.case("-o a regular file: refused, exit 7", refused(out_is_a_file, "not a folder"))
suite.case("-o a FIFO: refused, exit 7", refused(out_is_a_fifo, "not a folder"))
suite.case("OUTDIR/a.log a FIFO: refused, exit 7, no hang", refused(log_is_a_fifo, "a.log"))
suite.case("OUTDIR/b.decals a device: refused, exit 7", refused(package_is_a_device, "b.decals"))
suite.case("OUTDIR/b.log the scene's source: refused, exit 7",
           refused(log_is_the_source, "b.log"))
suite.case("OUTDIR/a.report.json the scene file: refused, exit 7",
           refused(report_is_the_scene, "a.report.json"))
suite.case("OUTDIR/summary.json a folder: refused before any scene, exit 7",
           refused(summary_is_a_folder, "summary.json"))
suite.case("other files in OUTDIR are left as they were", other_files_left_alone)
suite.case("submit: job scripts run by /bin/sh keep odd paths byte for byte", submit_odd_paths)
suite.case("submit: N=08 is 8; 0, -1, 1e3 refused", submit_n_leading_zero)
suite.case("submit: DECALPREP_SUBMIT_DRY=1 writes the job scripts, calls no sbatch", submit_dry_run)
suite.case("cluster stop: leaves a recorded pid that is not its daemon", cluster_stop_checks_pids)
suite.case("cluster start: the state folder reaches su as one word", cluster_start_quotes_state)
sys.exit(suite.finish())
