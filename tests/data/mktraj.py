#!/usr/bin/python3
"""mktraj.py — a crom/trajectory with an analytic displacement field, for tests.

    mktraj.py MESH.h5 OUT.h5 [--frames F] [--modes K] [--decay D] [--amp A]
              [--seed S] [--rest] [--nan-frame F]

Writes the layout of schemas/trajectory.md (every required attribute and
frame field) on the mesh of MESH.h5. Frame f has

    u(X) = sum_k a_fk phi_k(xi),   xi = (X - c) / L

with c the centre and L the largest half-extent of the mesh's bounding box
(the same physical fields on every mesh of the same box), K smooth analytic
modes phi_k (below), and a_fk = A L decay^k N(0, 1) drawn from --seed. The
velocity is the same sum with independent coefficients. --rest makes frame 0
the rest state (u = v = 0); --nan-frame puts a NaN into that frame.
Energies and solver fields are zero (no simulation made them).
"""
import argparse
import h5py
import numpy as np

MODES = [
    lambda x, y, z: (0 * x, x * x, 0 * x),                       # bending
    lambda x, y, z: (-z * y, 0 * x, x * y),                      # twist about y
    lambda x, y, z: (x, -0.3 * y, -0.3 * z),                     # stretch
    lambda x, y, z: (y, 0 * x, 0 * x),                           # shear
    lambda x, y, z: (x * (1 - y * y), 0 * x, z * (1 - y * y)),   # bulge
    lambda x, y, z: (0 * x, 0 * x, np.sin(np.pi * x)),           # wave
    lambda x, y, z: (0 * x, x * np.sin(np.pi * z), 0 * x),
    lambda x, y, z: (z * np.cos(np.pi * y), 0 * x, 0 * x),
]

FIELDS = ["time", "step", "displacement", "velocity", "kinetic_energy", "elastic_energy",
          "external_energy", "total_energy", "newton_iterations", "residual", "step_seconds"]


def basis(X):
    lo, hi = X.min(0), X.max(0)
    c, L = (lo + hi) / 2, (hi - lo).max() / 2
    xi = (X - c) / L
    return np.stack([np.stack(m(*xi.T), 1) for m in MODES], 0), L   # [K][nv][3]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("mesh")
    p.add_argument("out")
    p.add_argument("--frames", type=int, default=40)
    p.add_argument("--modes", type=int, default=5)
    p.add_argument("--decay", type=float, default=1.0)
    p.add_argument("--amp", type=float, default=0.05)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--rest", action="store_true")
    p.add_argument("--nan-frame", type=int, default=-1)
    a = p.parse_args()
    with h5py.File(a.mesh, "r") as m:
        X = m["vertices"][()]
        T = m["tets"][()]
        regions = {k: (m["regions"][k][()], m["regions"][k].attrs["source"]) for k in m.get("regions", {})}
    phi, L = basis(X)
    K = a.modes
    rng = np.random.default_rng(a.seed)
    sig = a.amp * L * a.decay ** np.arange(K)
    A = rng.standard_normal((a.frames, K)) * sig
    Ad = rng.standard_normal((a.frames, K)) * sig
    if a.rest:
        A[0] = 0
        Ad[0] = 0
    U = np.einsum("fk,kvc->fvc", A, phi[:K])
    V = np.einsum("fk,kvc->fvc", Ad, phi[:K])
    if 0 <= a.nan_frame < a.frames:
        U[a.nan_frame, len(X) // 2, 1] = np.nan
    F, nv = a.frames, len(X)
    dt = 0.01
    with h5py.File(a.out, "w") as f:
        f.attrs["schema"] = "crom/trajectory"
        f.attrs["schema_version"] = np.int64(1)
        f.attrs["history"] = "mktraj.py %s (analytic test field, %d modes, seed %d)" % (a.mesh, K, a.seed)
        f.attrs["crom_version"] = "0.1.0"
        f.attrs["complete"] = np.int64(1)
        f.attrs["scenario"] = "--dt 0.01\n--steps %d" % (F - 1)
        f.attrs["dt"] = dt
        f.attrs["every"] = np.int64(1)
        f.attrs["steps"] = np.int64(F - 1)
        f.attrs["youngs"] = 1e5
        f.attrs["poisson"] = 0.3
        f.attrs["density"] = 1000.0
        f.attrs["gravity"] = np.zeros(3)
        # units and descriptions as lib/io/schema.c has them (crom-info --check)
        f["mesh/vertices"] = X
        f["mesh/vertices"].attrs.update(units="m", description="rest positions X of the vertices")
        f["mesh/tets"] = T
        f["mesh/tets"].attrs.update(units="1", description="0-based vertex indices of each tetrahedron, "
                                    "positively oriented")
        for k, (v, source) in regions.items():
            f["mesh/regions/" + k] = v
            f["mesh/regions/" + k].attrs.update(units="1", source=source,
                                                description="sorted 0-based vertex indices of this named region")
        g = f.create_group("frames")
        g.attrs["fields"] = ",".join(FIELDS)
        data = {"time": np.arange(F) * dt, "step": np.arange(F, dtype=float),
                "displacement": U, "velocity": V}
        units = {"time": "s", "displacement": "m", "velocity": "m/s", "step_seconds": "s"}
        for name in FIELDS:
            d = data.get(name, np.zeros(F))
            ds = g.create_dataset(name, data=d, maxshape=(None,) + d.shape[1:], chunks=True)
            ds.attrs["units"] = units.get(name, "J" if "energy" in name else "1")
            ds.attrs["description"] = name


if __name__ == "__main__":
    main()
