#!/usr/bin/python3
"""benchskin.py — the table of the soft bar of `make bench` datafree
(pipelines/bench.mk, issue 14): the skinning subspaces against crom-fullsim.
Markdown on stdout, DIR/datafree2.csv beside.

  benchskin.py DIR "ROWS" ["MAPS"]
      ROWS: KIND-SCHEME, weights (eigen, trained; mderiv: modes and their
            modal derivatives, a linear basis) and cubature (opt:
            optimized, metis)
      MAPS: KIND-SCHEME, continuous fields (sfield: over skinning eigenmodes,
            field: a trained W(X)), maps of one mesh (energy, neuralmodes) and
            linear modes (modes) stepped with --model over every tet (all) or
            an optimized cubature of their features (opt); mderiv: modes with
            their modal derivatives
"""
import csv, re, statistics, sys

import h5py


def col(path, name):
    with open(path) as f:
        return [float(r[name]) for r in csv.DictReader(f)]


def frames(path):
    """crom-diff's per-frame relative errors, frame by frame"""
    rows = [l.split() for l in open(path).read().strip().splitlines() if l.strip()[:1].isdigit()]
    return [float(r[2]) for r in rows]


def run_error(path):
    last = open(path).read().strip().splitlines()[-1]
    m = re.search(r"relative displacement error ([0-9.eE+-]+) over", last)
    return float(m.group(1)) if m else float("nan")


def collapsed(path):
    m = re.search(r"^collapse: ([0-9]+) of ([0-9]+)", open(path).read(), re.M)
    return (int(m.group(1)), int(m.group(2))) if m else (None, None)


MAP_NAMES = {"sfield": "continuous field over skinning eigenmodes (skin-field)",
             "sfref": "skin-field trained 1 min, then refined along its static run (--init-model --latents)",
             "field": "continuous field, trained W(X) (energy-field)",
             "energy": "energy map (Sharp et al.)",
             "emref": "energy map trained 10,000 steps, then refined 3,000 along its static run (--init-model --latents)",
             "neuralmodes": "neural modes (Wang et al.)",
             "nmseed": "neural modes seeded with modal derivatives, untrained (quadratic manifold)",
             "nmrun": "neural modes, derivative seed, tangent-anchored, sampled along the seed's static run",
             "modes": "linear modes",
             "mderiv": "linear modes and their modal derivatives (Barbic and James)"}


def map_rows(out, maps, nt, fm):
    """the continuous fields' rows, in the columns of the skinning rows"""
    t = []
    for r in maps:
        kind, scheme = r.split("-")
        model = h5py.File(f"{out}/df2-map-{kind}.h5")
        tets = len(h5py.File(f"{out}/df2-mcub-{kind}.h5")["elements"]) if scheme == "opt" else nt
        red = col(f"{out}/df2-mred-{r}.csv", "seconds")
        it = col(f"{out}/df2-mred-{r}.csv", "iterations")
        rm = statistics.median(red)
        dyn = frames(f"{out}/df2-mdiff-{r}.txt")
        c, d = collapsed(f"{out}/df2-mmetrics-{kind}.txt")
        t.append(["%s, %s" % (MAP_NAMES.get(kind, kind), "optimized cubature" if scheme == "opt" else "every tet"),
                  int(model.attrs["handles"]) if "handles" in model.attrs else None, int(model.attrs["rank"]),
                  int(model.attrs["training_steps"]) if "training_steps" in model.attrs else None,
                  float(model.attrs.get("training_seconds", float("nan"))), tets, 1e3 * rm, sum(it) / len(it),
                  fm / rm, run_error(f"{out}/df2-mdiff-{r}.txt"), dyn[1] if len(dyn) > 1 else float("nan"),
                  frames(f"{out}/df2-msdiff-{r}.txt")[-1], c, d])
    return t


def main(out, rows, maps):
    mesh = h5py.File(f"{out}/df-mesh.h5")
    nv, nt = len(mesh["vertices"]), len(mesh["tets"])
    full = col(f"{out}/df2-full.csv", "seconds")
    fm = statistics.median(full)
    sfull = h5py.File(f"{out}/df2-sfull.h5")
    X = sfull["mesh/vertices"][()]
    tip = X[:, 0].argmax()
    sag = -sfull["frames/displacement"][-1, tip, 1]
    t = []
    for r in rows:
        kind, scheme = r.split("-")
        model = h5py.File(f"{out}/df2-skin-{kind}.h5")
        cub = h5py.File(f"{out}/df2-cub-{r}.h5")
        red = col(f"{out}/df2-red-{r}.csv", "seconds")
        it = col(f"{out}/df2-red-{r}.csv", "iterations")
        rm = statistics.median(red)
        dyn = frames(f"{out}/df2-diff-{r}.txt")
        c, d = collapsed(f"{out}/df2-metrics-{kind}.txt")
        steps = int(model.attrs["training_steps"]) if "training_steps" in model.attrs else None
        name = "modes and modal derivatives" if kind == "mderiv" else kind
        handles = int(model.attrs["handles"]) if "handles" in model.attrs else None
        t.append(["%s, %s cubature" % (name, "optimized" if scheme == "opt" else "METIS"), handles, int(model.attrs["rank"]), steps,
                  float(model.attrs.get("training_seconds", float("nan"))), len(cub["elements"]), 1e3 * rm,
                  sum(it) / len(it), fm / rm, run_error(f"{out}/df2-diff-{r}.txt"), dyn[1] if len(dyn) > 1 else float("nan"),
                  frames(f"{out}/df2-sdiff-{r}.txt")[-1], c, d])
    t += map_rows(out, maps, nt, fm)
    print("### The soft bar: skinning subspaces (crom; one core, issue 14)\n")
    print(f"The bar of the table above ({nv} vertices, {nt} tets) made soft: nu = 0.45 and E such that the free end "
          f"sags {sag:.3f} m ({100 * sag:.0f}% of the length) at rest under gravity; 100 steps of 0.05 s. Each "
          f"subspace runs over an optimized cubature fitted, with no simulation data, to the poses of its own runs "
          f"(dynamic and static) over a fine METIS cubature, or over a METIS cubature.\n")
    print("| weights, cubature | handles | latent dim | training steps | build (s) | cubature tets | median reduced step (ms) | "
          "iterations/step | speedup | dynamic error | first-step error | static sag error | collapsed dims |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for x in t:
        print("| %s | %s | %d | %s | %.3g | %d | %.3f | %.1f | %.3g× | %.4f | %.4f | %.4f | %s |" % (
            x[0], "—" if x[1] is None else x[1], x[2], "—" if x[3] is None else x[3], x[4], x[5], x[6], x[7], x[8], x[9], x[10], x[11],
            "?" if x[12] is None else "%d of %d" % (x[12], x[13])))
    print("| full space (crom-fullsim), the reference | | %d | — | — | %d | %.3f | | 1× | 0 | 0 | 0 | |" % (
        3 * nv, nt, 1e3 * fm))
    print("\nBuild: the eigensolve (eigen) or the training, stopped by the clock (trained weights; the continuous "
          "fields: the eigensolve and phi's training for skin-field, both networks for energy-field), with the orthonormal "
          "coordinates. Dynamic error: crom-diff against crom-fullsim over the run; first-step error: frame 1 of it; "
          "static sag error: the last frame of the same load damped (--damping 10) against the damped full run. "
          "Collapsed dims: crom-metrics, normalized Gram eigenvalues below 0.01.\n")
    with open(f"{out}/datafree2.csv", "w") as f:
        w = csv.writer(f)
        w.writerow(["weights", "handles", "latent_dim", "training_steps", "build_s", "cubature_tets",
                    "reduced_step_ms", "iterations_per_step", "speedup", "dynamic_error", "first_step_error",
                    "static_sag_error", "collapsed_dims"])
        w.writerows([["" if v is None else v for v in x[:13]] for x in t])
        w.writerow(["full space (crom-fullsim)", "", 3 * nv, "", "", nt, 1e3 * fm, "", 1, 0, 0, 0, ""])


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit("usage: benchskin.py DIR ROWS [MAPS]")
    main(sys.argv[1], sys.argv[2].split(), sys.argv[3].split() if len(sys.argv) == 4 else [])
