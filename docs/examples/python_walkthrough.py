# A notebook-style walk through the vtsim Python module (docs/python.md). Each "# %%" cell runs in
# Jupyter / VS Code as a cell, or the whole file as a script:
#   PYTHONPATH=build/python /usr/bin/python3 docs/examples/python_walkthrough.py [OUT_DIR]
# Plots go to OUT_DIR (default out/python) through matplotlib when it is installed (Debian:
# python3-matplotlib); otherwise the figures are printed.

# %% Setup: a 20-second walk through the test town, in a VT.
import concurrent.futures
import os
import sys
import tempfile

import vtsim

out_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join("out", "python")
os.makedirs(out_dir, exist_ok=True)
try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    plt = None
try:
    import pandas as pd
except ImportError:
    pd = None

repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
trace = os.path.join(repo, "tests", "data", "town_walk.csv")
t = vtsim.load_trace(trace)
print(f"{trace}: {len(t['t_s'])} poses over {t['t_s'][-1]:.1f} s, "
      f"from ({t['pos_m'][0, 0]:.1f}, {t['pos_m'][0, 1]:.1f}) m")
town = {"run": {"system": "vt"}, "scene": {"kind": "town"}, "view": {"divisor": 8}}

# %% One replay: the summary as a dict, the per-frame series as numpy arrays.
r = vtsim.replay(config=town, trace=trace)
s = r["summary"]
print(f"blurry {100 * s['popin']['blurry_fraction_mean']:.2f} % mean, latency p99 {s['latency_ms']['p99']:.1f} ms, "
      f"disk {s['bandwidth']['disk_read_MBps']:.2f} MB/s")
f = r["frames"]
if plt:
    fig, ax = plt.subplots(figsize=(8, 3))
    ax.plot(f["t_s"], 100 * f["blurry_fraction"], label="blurry %")
    ax.plot(f["t_s"], f["uploads"], label="uploads / frame")
    ax.set_xlabel("s")
    ax.legend()
    fig.savefig(os.path.join(out_dir, "frames.png"), dpi=100, bbox_inches="tight")
    print("wrote", os.path.join(out_dir, "frames.png"))
else:
    worst = int(f["blurry_fraction"].argmax())
    print(f"worst frame {worst} at {f['t_s'][worst]:.2f} s: {100 * f['blurry_fraction'][worst]:.1f} % blurry, "
          f"{int(f['needs'][worst])} tiles needed")

# %% Pool sizes on threads: the GIL is released during each replay, so they run in parallel.
pools = [64, 128, 256, 512]
with concurrent.futures.ThreadPoolExecutor(max_workers=2) as ex:
    runs = list(ex.map(lambda n: vtsim.replay(config={**town, "vt.pool_pages": n}, trace=trace)["summary"], pools))
for n, s in zip(pools, runs):
    print(f"pool {n:4} pages: blurry {100 * s['popin']['blurry_fraction_mean']:6.2f} %, "
          f"{s['vt']['pool']['evictions']} evictions")

# %% A sweep: rows that pandas takes as they are.
with tempfile.TemporaryDirectory() as tmp:
    spec = os.path.join(tmp, "sweep.toml")
    with open(spec, "w") as fh:
        fh.write(f'set = ["run.system=vt", "scene.kind=town", "view.divisor=8"]\ntraces = ["{trace}"]\n'
                 'metrics = ["popin.blurry_fraction_mean", "latency_ms.p99", "bandwidth.disk_read_MBps"]\n'
                 '[grid]\n"vt.pool_pages" = [128, 512]\n"upload.tiles_per_frame" = [4, 16]\n')
    rows = vtsim.sweep(spec)
if pd is not None:
    df = pd.DataFrame(rows)
    print(df.pivot(index="vt.pool_pages", columns="upload.tiles_per_frame", values="popin.blurry_fraction_mean"))
else:
    for row in rows:
        print(row["vt.pool_pages"], row["upload.tiles_per_frame"], row["popin.blurry_fraction_mean"])

# %% The pool's miss-ratio curve, LRU against Belady.
m = vtsim.mrc(trace=trace, config=town, sizes=17, opt=True)
if plt:
    fig, ax = plt.subplots(figsize=(6, 3))
    ax.plot(m["capacity"], m["miss_ratio"], label="LRU")
    ax.plot(m["capacity"], m["belady_miss_ratio"], label="Belady")
    ax.set_xlabel("pool pages")
    ax.set_ylabel("miss ratio")
    ax.legend()
    fig.savefig(os.path.join(out_dir, "mrc.png"), dpi=100, bbox_inches="tight")
    print("wrote", os.path.join(out_dir, "mrc.png"))
else:
    for c, lru, opt in zip(m["capacity"], m["miss_ratio"], m["belady_miss_ratio"]):
        print(f"{int(c):8} pages  LRU {lru:.4f}  Belady {opt:.4f}")

# %% Capacity of this texture as a VT at 1080p.
c = vtsim.capacity(config=town, system="vt", screen=(1920, 1080))
print(f"{c['pages']} pages, page table {c['page_table_bytes'] / 2**20:.1f} MiB, pool {c['pool_pages']} pages")
