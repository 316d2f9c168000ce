"""Runs a command and measures it, for the scripted benches beside this file."""
import os
import subprocess
import time


def measured(cmd, env=None):
    """Runs `cmd` (stdout discarded) and returns (wall seconds, CPU seconds,
    peak resident MiB) of the child, from the kernel (wait4's rusage).
    Raises RuntimeError with the end of its stderr when it fails."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    err = p.stderr.read()
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError("%s failed: %s" % (" ".join(cmd), err.decode()[-2000:]))
    return wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0
