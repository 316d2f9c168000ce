"""What the scripted benches beside this file share: running and measuring a
command, their --build-dir and --out options, and writing their CSV."""
import csv
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


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def add_build_and_out(ap):
    """The options the scripted benches share: --build-dir (the build whose
    decalprep runs) and --out (where CSV and charts go)."""
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "report"))


def decalprep_of(a):
    """The decalprep binary of --build-dir; makes --out."""
    os.makedirs(a.out, exist_ok=True)
    return os.path.join(a.build_dir, "tools", "decalprep", "decalprep")


def write_rows(path, rows):
    """Writes `rows` (dicts with the same keys) as CSV with a header."""
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)


def vertex_counts(text):
    """--vertices "1e6,1e7" as integers."""
    return [int(float(s)) for s in text.split(",")]


def bars_svg(path, title, groups, series):
    """A grouped bar chart as SVG: `groups` is [(label, [value per series],
    second label or "")], `series` [(name, colour)]; each bar is labelled
    with its value, each group with its labels, the series in a legend."""
    w, h, left, bottom = max(640, 110 * len(groups) + 80), 320, 60, 260
    top = max(max(vals) for _, vals, _ in groups) * 1.15 or 1.0
    bw = (w - left - 20) / len(groups) / (len(series) + 1)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" '
           'font-size="11">', f'<text x="{left}" y="16">{title}</text>',
           f'<line x1="{left}" y1="{bottom}" x2="{w - 10}" y2="{bottom}" stroke="black"/>']
    for i, (label, vals, second) in enumerate(groups):
        x0 = left + 10 + i * (len(series) + 1) * bw
        for j, ((_, colour), v) in enumerate(zip(series, vals)):
            bh = (bottom - 40) * v / top
            x = x0 + j * bw
            out.append(f'<rect x="{x:.1f}" y="{bottom - bh:.1f}" width="{bw * 0.9:.1f}" height="{bh:.1f}" '
                       f'fill="{colour}"/><text x="{x:.1f}" y="{bottom - bh - 3:.1f}">{v:.0f}</text>')
        out.append(f'<text x="{x0:.1f}" y="{bottom + 14}">{label}</text>')
        if second:
            out.append(f'<text x="{x0:.1f}" y="{bottom + 28}">{second}</text>')
    for j, (name, colour) in enumerate(series):
        out.append(f'<rect x="{w - 190}" y="{30 + 16 * j}" width="10" height="10" fill="{colour}"/>'
                   f'<text x="{w - 175}" y="{39 + 16 * j}">{name}</text>')
    out.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")
