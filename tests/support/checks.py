"""What the Python tests of tests/ share: check(), which records and prints
a failure and returns the condition, the `failures` it fills (a test exits 1
when it is not empty), and run(), a subprocess with its output captured."""
import subprocess

failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL: " + msg, flush=True)
    return cond


def run(args, **kw):
    return subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)
