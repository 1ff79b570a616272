#!/usr/bin/env bash
# crom-export cell data and times: a uniformly deformed tet's volume, J,
# stable neo-Hookean energy density and von Mises Cauchy stress against
# values computed here from the law's formula (Smith et al. 2018 as
# schemas/trajectory.md states it), in VTU (meshio) and XDMF (meshio and
# h5py, with units); the material from the file or from --youngs/--poisson;
# a full run's cells sum to its elastic energy; a decoded latent run's cells
# follow its decoded displacement; frame times written with the fewest
# digits that read back exactly (1000 steps of 0.001).
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"

# 1. one tet (and a second one, to check the ordering) under two uniform
#    deformations F: a stretch diag(1.3, 0.9, 1.1) and a stretch with shear
$PY - <<'PYEOF'
import h5py, numpy as np
X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float) * 0.2
T = np.array([[0, 1, 2, 3], [1, 2, 3, 4]], np.int32)
if np.linalg.det(np.stack([X[4] - X[1], X[2] - X[1], X[3] - X[1]], 1)) < 0:
    T[1] = [1, 3, 2, 4]
Fs = [np.diag([1.3, 0.9, 1.1]), np.array([[1.2, 0.3, 0.0], [0.1, 0.95, 0.2], [0.0, -0.1, 1.05]])]
U = np.stack([X @ F.T - X for F in Fs]); V = np.zeros_like(U)
def attrs(f, schema):
    f.attrs["schema"] = schema; f.attrs["schema_version"] = np.int64(1); f.attrs["history"] = "test"
with h5py.File("tet.h5", "w") as f:
    attrs(f, "crom/mesh"); f["vertices"] = X; f["tets"] = T
for name, mat in (("traj.h5", True), ("nomat.h5", False)):
    with h5py.File(name, "w") as f:
        attrs(f, "crom/trajectory"); f.attrs["complete"] = np.int64(1); f.attrs["dt"] = 0.5
        if mat:
            f.attrs["youngs"] = 1e5; f.attrs["poisson"] = 0.3
        f["mesh/vertices"] = X; f["mesh/tets"] = T
        g = f.create_group("frames"); g.attrs["fields"] = "time,displacement,velocity"
        for k, d in (("time", np.array([0.0, 0.5])), ("displacement", U), ("velocity", V)):
            g.create_dataset(k, data=d, maxshape=(None,) + d.shape[1:], chunks=True)
PYEOF
crom-export -q -o a.vtu --frame 0 traj.h5
crom-export -q -o b.vtu traj.h5
crom-export -q -o run.xdmf traj.h5
crom-export -q -o c.vtu --youngs 1e5 --poisson 0.3 nomat.h5      # the material by flags
crom-export -q -o d.vtu --youngs 2e5 --poisson 0.3 traj.h5       # flags override the file
crom-export -o e.vtu nomat.h5 2>note.txt                         # no material: a note, no energy
grep -q "records no material" note.txt || fail "no note about the missing material: $(cat note.txt)"; ok
crom-export -q -o mesh.vtu tet.h5
$PY - <<'PYEOF' || fail "cell data against the stable neo-Hookean law"
import sys, h5py, meshio, numpy as np
E, nu = 1e5, 0.3
def law(F, E, nu):
    muL = E / (2 * (1 + nu)); laL = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = 4 / 3 * muL; la = laL + 5 / 6 * muL; al = 1 + 3 * mu / (4 * la)
    Ic = np.sum(F * F); J = np.linalg.det(F)
    psi = mu / 2 * (Ic - 3) - mu / 2 * np.log((Ic + 1) / 4) + la / 2 * ((J - al) ** 2 - (1 - al) ** 2)
    P = mu * (1 - 1 / (Ic + 1)) * F + la * (J - al) * J * np.linalg.inv(F).T   # dPsi/dF
    s = P @ F.T / J; d = s - np.trace(s) / 3 * np.eye(3)
    return J, psi, np.sqrt(1.5 * np.sum(d * d))
def close(a, b, what, rel=1e-12):
    if not np.all(np.abs(np.asarray(a) - b) <= rel * np.maximum(1.0, np.abs(b))):
        sys.exit("%s: %r, expected %r" % (what, a, b))
Fs = [np.diag([1.3, 0.9, 1.1]), np.array([[1.2, 0.3, 0.0], [0.1, 0.95, 0.2], [0.0, -0.1, 1.05]])]
X = h5py.File("tet.h5")["vertices"][()]
V = np.array([0.2 ** 3 / 6, 2 * 0.2 ** 3 / 6])      # the unit corner tet and the other one, scaled
for name, k, e in (("a.vtu", 0, E), ("b.vtu", 1, E), ("c.vtu", 1, E), ("d.vtu", 1, 2 * E)):
    m = meshio.read(name); cd = {n: v[0] for n, v in m.cell_data.items()}
    J, psi, vm = law(Fs[k], e, nu)
    close(cd["volume"], V, name + " volume")
    close(cd["J"], [J, J], name + " J")
    close(cd["energy_density"], [psi, psi], name + " energy density", 1e-11)
    close(cd["von_mises_stress"], [vm, vm], name + " von Mises stress", 1e-11)
    t = m.field_data["TimeValue"]
    close(t, [0.0, 0.5][k], name + " TimeValue")
J, psi, vm = law(Fs[0], E, nu)
print("stretch diag(1.3, 0.9, 1.1): J %.6f, energy density %.6g J/m^3, von Mises %.6g Pa" % (J, psi, vm))
e = meshio.read("e.vtu").cell_data
if "energy_density" in e or "von_mises_stress" in e or "J" not in e:
    sys.exit("without a material: %s" % sorted(e))
m = meshio.read("mesh.vtu")
if sorted(m.cell_data) != ["volume"] or "TimeValue" in m.field_data:
    sys.exit("bare mesh: %s %s" % (sorted(m.cell_data), sorted(m.field_data)))
close(m.cell_data["volume"][0], V, "bare mesh volume")
# XDMF: the same through meshio's TimeSeriesReader, and units in the heavy data
with meshio.xdmf.TimeSeriesReader("run.xdmf") as r:
    r.read_points_cells()
    for k in range(r.num_steps):
        t, pd, cd = r.read_data(k)
        J, psi, vm = law(Fs[k], E, nu)
        close(cd["J"][0], [J, J], "xdmf J %d" % k)
        close(cd["energy_density"][0], [psi, psi], "xdmf energy density %d" % k, 1e-11)
        close(cd["von_mises_stress"][0], [vm, vm], "xdmf stress %d" % k, 1e-11)
        close(cd["volume"][0], V, "xdmf volume %d" % k)
h = h5py.File("run.xdmf.h5")
units = {n: h[n].attrs["units"].decode() if isinstance(h[n].attrs["units"], bytes) else h[n].attrs["units"]
         for n in ("mesh/volume", "J/00001", "energy_density/00001", "von_mises_stress/00001",
                   "displacement/00001", "velocity/00001", "time")}
want = {"mesh/volume": "m^3", "J/00001": "1", "energy_density/00001": "J/m^3", "von_mises_stress/00001": "Pa",
        "displacement/00001": "m", "velocity/00001": "m/s", "time": "s"}
if units != want:
    sys.exit("units %s" % units)
print("vtu and xdmf cell data match the law at two deformations; units %s" % units)
PYEOF
ok
expect_error 64 "records no Poisson ratio: give --youngs and --poisson together" f.vtu -- crom-export -o f.vtu --youngs 1e5 nomat.h5
expect_error 64 "Poisson ratio nu = 0.7" f.vtu -- crom-export -o f.vtu --youngs 1e5 --poisson 0.7 traj.h5

# 2. a full run (through a pipe): its cells sum to its elastic energy, and
#    a reduced run decoded on the mesh has the cells of its decoded field
crom-mesh box --size 0.25 --region top='y>0.45' --region bottom='y<-0.45' -o box.h5
SC=(--velocity 'top=0,-2,0@0:0.04' --pin bottom --gravity 0,0,0 --dt 0.01 --steps 6 --youngs 2e5 --poisson 0.35)
crom-fullsim "${SC[@]}" -q -o full.h5 box.h5
crom-fullsim "${SC[@]}" -q box.h5 | crom-export --format pvd -q -o full.pvd
crom-sample --points all -q -o samples.h5 full.h5
crom-fitfield --basis pod --rank 4 -q -o pod.h5 samples.h5
crom-cubature --model pod.h5 --scheme all -q -o cub.h5 box.h5
crom-reducedstep --cubature cub.h5 "${SC[@]}" -q -o red.h5
crom-export -q --model pod.h5 --mesh box.h5 -o red.xdmf red.h5
$PY - <<'PYEOF' || fail "cell data of full and reduced runs"
import sys, h5py, meshio, numpy as np
f = h5py.File("full.h5"); Eel = f["frames/elastic_energy"][()]
E, nu = 2e5, 0.35
muL = E / (2 * (1 + nu)); laL = E * nu / ((1 + nu) * (1 - 2 * nu))
mu = 4 / 3 * muL; la = laL + 5 / 6 * muL; al = 1 + 3 * mu / (4 * la)
def psi_of(X, T, u):
    Dm = np.stack([X[T[:, i]] - X[T[:, 0]] for i in (1, 2, 3)], 2)
    x = X + u; Ds = np.stack([x[T[:, i]] - x[T[:, 0]] for i in (1, 2, 3)], 2)
    F = Ds @ np.linalg.inv(Dm); Ic = np.einsum("tij,tij->t", F, F); J = np.linalg.det(F)
    return np.linalg.det(Dm) / 6, mu / 2 * (Ic - 3) - mu / 2 * np.log((Ic + 1) / 4) + la / 2 * ((J - al) ** 2 - (1 - al) ** 2)
for k in range(len(Eel)):
    m = meshio.read("full/full_%05d.vtu" % k)
    s = np.sum(m.cell_data["volume"][0] * m.cell_data["energy_density"][0])
    if abs(s - Eel[k]) > 1e-9 * max(Eel.max(), 1e-30):
        sys.exit("frame %d: cells sum to %r J, the run says %r J" % (k, s, Eel[k]))
print("full run: volume x energy density sums to the elastic energy in all %d frames (last %.6g J)" % (len(Eel), Eel[-1]))
with meshio.xdmf.TimeSeriesReader("red.xdmf") as r:
    X, cells = r.read_points_cells(); T = cells[0].data
    for k in range(r.num_steps):
        t, pd, cd = r.read_data(k)
        V, psi = psi_of(X, T, pd["displacement"])
        if not np.allclose(cd["energy_density"][0], psi, rtol=1e-9, atol=1e-9 * max(psi.max(), 1)):
            sys.exit("reduced frame %d: energy density differs from the decoded field's" % k)
        if not np.allclose(cd["volume"][0], V, rtol=1e-13):
            sys.exit("reduced frame %d: volumes" % k)
print("reduced run: cell data from the decoded displacement in %d frames" % r.num_steps)
PYEOF
ok

# 3. times: 1000 steps of 0.001 (time = step * dt) come out as the shortest
#    decimal that reads back exactly, in PVD, XDMF and each VTU's TimeValue
$PY - <<'PYEOF'
import h5py, numpy as np
src = h5py.File("traj.h5"); n = 1001
with h5py.File("long.h5", "w") as f:
    for k, v in src.attrs.items():
        f.attrs[k] = v
    f["mesh/vertices"] = src["mesh/vertices"][()]; f["mesh/tets"] = src["mesh/tets"][()]
    g = f.create_group("frames"); g.attrs["fields"] = "time,displacement,velocity"
    U = np.zeros((n, 5, 3))
    for k, d in (("time", np.arange(n) * 0.001), ("displacement", U), ("velocity", U)):
        g.create_dataset(k, data=d, maxshape=(None,) + d.shape[1:], chunks=True)
PYEOF
crom-export -q -o long.pvd long.h5
crom-export -q -o long.xdmf long.h5
$PY - <<'PYEOF' || fail "shortest round-trip times"
import re, sys, numpy as np
t = np.arange(1001) * 0.001
pvd = re.findall(r'timestep="([^"]*)"', open("long.pvd").read())
xdmf = re.findall(r'<Time Value="([^"]*)"', open("long.xdmf").read())
vtu = [re.search(r'Name="TimeValue"[^>]*>([^<]*)<', open("long/long_%05d.vtu" % k).read()).group(1) for k in (3, 999, 1000)]
for name, got, want in (("pvd", pvd, t), ("xdmf", xdmf, t), ("vtu", vtu, t[[3, 999, 1000]])):
    if len(got) != len(want):
        sys.exit("%s: %d times for %d frames" % (name, len(got), len(want)))
    for g, w in zip(got, want):
        # exact, and no longer than Python's repr (the shortest round trip)
        if float(g) != w or len(g) > len(repr(float(w))):
            sys.exit("%s: time %s for %r" % (name, g, float(w)))
print("1001 times as shortest round-trip text, e.g. %s %s %s" % (pvd[3], pvd[999], pvd[1000]))
PYEOF
ok
done_checks
