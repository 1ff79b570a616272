#!/usr/bin/python3
"""benchtab.py — the tables of `make bench` (pipelines/bench.mk) from the files
the runs left: crom-fullsim/crom-reducedstep --stats CSVs, crom-diff outputs,
and the attributes of models and cubatures. Markdown on stdout, CSV beside.

  benchtab.py tables DIR "SIZES" "LOADS"   LiCROM Tables 1 and 2 for crom
  benchtab.py training DIR                  training speed and time to accuracy
"""
import csv, re, statistics, sys

import h5py
import numpy as np


def col(path, name):
    with open(path) as f:
        return [float(r[name]) for r in csv.DictReader(f)]


def diff_error(path):
    last = open(path).read().strip().splitlines()[-1]
    m = re.search(r"relative displacement error ([0-9.eE+-]+) over", last)
    return float(m.group(1)) if m else float("nan")


def tables(out, sizes, loads):
    t1, t2 = [], []
    for s in sizes:
        mesh = h5py.File(f"{out}/t-mesh-{s}.h5")
        nv, nt = len(mesh["vertices"]), len(mesh["tets"])
        cub = h5py.File(f"{out}/t-cub-{s}.h5")
        elems = cub["elements"][()]
        cverts = len(np.unique(cub["mesh/tets"][()][elems]))
        model = h5py.File(f"{out}/t-model-{s}.h5")
        gen = 0.0
        for l in loads:
            full = col(f"{out}/t-full-{s}-{l}.csv", "seconds")
            red = col(f"{out}/t-red-{s}-{l}.csv", "seconds")
            gen += sum(full)
            fm, rm = statistics.median(full), statistics.median(red)
            t1.append([f"cube {l}", nv, nt, cverts, len(elems), 1e3 * fm, 1e3 * rm, fm / rm,
                       diff_error(f"{out}/t-diff-{s}-{l}.txt")])
        frames = len(h5py.File(f"{out}/t-samples-{s}.h5")["frame_source"])
        t2.append([nv, frames, len(loads), gen / 60, float(model.attrs.get("training_seconds", float("nan"))),
                   float(model.attrs.get("reconstruction_error", float("nan"))),
                   1e3 * float(cub.attrs.get("selection_seconds", float("nan"))),
                   1e3 * float(cub.attrs.get("w_seconds", float("nan")))])
    print("### Table 1: performance (crom; r = 20, optimized cubature, one core)\n")
    print("| example | vertices | tets | cubature vertices | cubature tets | full step (ms) | reduced step (ms) | speedup | relative error |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in t1:
        print("| %s | %d | %d | %d | %d | %.1f | %.3f | %.0f× | %.4f |" % tuple(r))
    print("\nStep costs are medians over the steps; the error is crom-diff's mass-weighted relative "
          "displacement error of the reduced run against crom-fullsim over the whole run (LiCROM "
          "reports 17–56× speedups, Table 1).\n")
    print("### Table 2: precomputation (crom; one core)\n")
    print("| vertices | training snapshots | loadings | data generation (min) | training (s) | reconstruction error | cubature selection (ms) | evaluating W (ms) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in t2:
        print("| %d | %d | %d | %.2f | %.0f | %.4f | %.1f | %.1f |" % tuple(r))
    print("\nLiCROM's Table 2 reports hours of GPU training; crom trains its lsq neural field on one "
          "CPU core within the time shown (crom-fitfield --minutes).\n")
    with open(f"{out}/table1.csv", "w") as f:
        w = csv.writer(f)
        w.writerow(["example", "vertices", "tets", "cubature_vertices", "cubature_tets", "full_step_ms",
                    "reduced_step_ms", "speedup", "relative_error"])
        w.writerows(t1)
    with open(f"{out}/table2.csv", "w") as f:
        w = csv.writer(f)
        w.writerow(["vertices", "snapshots", "loadings", "data_generation_min", "training_s",
                    "reconstruction_error", "cubature_selection_ms", "evaluating_W_ms"])
        w.writerows(t2)


def training(out):
    samples = h5py.File(f"{out}/tr-samples.h5")
    u = samples["displacements"][()].astype(float)
    mean_u2 = float(np.mean(np.sum(u * u, axis=-1)))
    rows = []
    for kind in ("lsq", "pointnet"):
        m = h5py.File(f"{out}/tr-{kind}.h5")
        loss, secs = m["training/loss"][()], m["training/seconds"][()]
        rel = np.sqrt(np.maximum(loss, 0) / mean_u2)
        with open(f"{out}/training-{kind}.csv", "w") as f:
            w = csv.writer(f)
            w.writerow(["epoch", "seconds", "relative_error"])
            w.writerows([[i, s, r] for i, (s, r) in enumerate(zip(secs, rel))])
        below = np.nonzero(rel < 0.02)[0]
        t2pct = float(secs[below[0]]) if len(below) else float("nan")
        log = open(f"{out}/tr-{kind}.log").read()
        tp = re.search(r"([0-9.e+]+) points/s through W forward\+backward", log)
        rows.append([kind, len(loss), float(secs[-1]), float(m.attrs["reconstruction_error"]), t2pct,
                     float(tp.group(1)) if tp else float("nan")])
    nv = [len(h5py.File(f"{out}/tr-mesh-{s}.h5")["vertices"]) for s in ("2", "2.5", "3.5", "6", "box")]
    print("### Training the neural field (crom-fitfield, r = 20, one core)\n")
    print(f"Five shapes from sphere to cube ({min(nv)}–{max(nv)} vertices), {len(samples['frame_source'])} "
          f"frames of compression, 2048 vertex samples per frame.\n")
    print("| encoder | epochs | training (s) | final relative error | time to 2% (s) | points/s through W (fwd+bwd) |")
    print("|---|---:|---:|---:|---:|---:|")
    for r in rows:
        print("| %s | %d | %.0f | %.4f | %s | %.3g |" % (r[0], r[1], r[2], r[3],
              "not reached" if r[4] != r[4] else "%.1f" % r[4], r[5]))
    print("\nThe issue's target: lsq below 2% within 10 minutes on one core (LiCROM needed 4.9 h "
          "on a GPU for its five-shape set). Relative error per epoch = sqrt(training loss / "
          "mean |u|^2) of the samples; the final error is the model's reconstruction_error.\n")


if __name__ == "__main__":
    if sys.argv[1] == "tables":
        tables(sys.argv[2], sys.argv[3].split(), sys.argv[4].split())
    elif sys.argv[1] == "training":
        training(sys.argv[2])
    else:
        sys.exit("usage: benchtab.py tables|training DIR ...")
