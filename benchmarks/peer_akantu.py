"""Peer comparison: the expanding bar in dolfrag and in Akantu.

The same 2D problem in both codes: the bar of dolfrag's built-in case ``expanding-bar``
(0.12 m x 0.04 m, plane strain, E = 35 GPa, nu = 0.2, rho = 2350 kg/m^3, linear-softening
cohesive law sigma_c, G_c), stretched at a uniform strain rate (v_x = eps_dot (x - L/2) at
t = 0, both ends' x velocity held at -/+ eps_dot L / 2), on the same triangles, to the same
physical end time. Akantu (PyPI ``akantu``) runs in its own virtual environment, twice:

* intrinsic: cohesive elements on every facet from the start, ``cohesive_bilinear`` (the
  linear-softening law with an initial elastic branch of stiffness sigma_c / delta_0 =
  STIFFNESS_RATIO E / h, Akantu's intrinsic form of ``cohesive_linear``);
* extrinsic: ``cohesive_linear`` elements inserted where the facet stress reaches sigma_c
  (``checkCohesiveStress`` every step). dolfrag's ``linear_softening`` is rigid until
  sigma_c, so this is the variant it corresponds to.

The mesh is written once, by the gmsh script below, as MSH 2.2 (what Akantu's reader and
its examples use, ``gmsh -format msh2``), and dolfrag reads the same file
(``geometry.kind = "file"``). Physical tags differ across dimensions: Akantu keys the
physical names by tag alone (measured: with ``concrete`` = 2D tag 1, the 1D group ``left``
= tag 1 vanished).

Printed: wall time of each run (setup and time loop, no output), their ratios, fragment
counts (the same rule for all: pieces with at least post/expanding.MASS_SHARE of the mass)
and dissipated energies (J per metre of depth: Akantu's 2D energies are per unit
thickness; the initial kinetic energy of both is checked against 1/2 rho W eps_dot^2
L^3 / 12). Usage (the dolfrag venv's python; ``make peer`` does it all)::

    python benchmarks/peer_akantu.py [--size 0.002] [--end 3e-5] [--strain-rate 600] \\
        [--akantu-python .venv-akantu/bin/python] [--out results/peer]
"""
import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASE = "expanding-bar"
# Akantu's intrinsic elastic branch, sigma_c / delta_0 = STIFFNESS_RATIO E / h: the paper's
# interface stiffness rule (dolfrag's RCCM default), ~5 % artificial compliance in 1D.
STIFFNESS_RATIO = 10.0
# Akantu's explicit step as a share of its bulk stable step (getStableTimeStep, which ignores
# the cohesive elements), measured on the case (2 mm, 600 1/s): the dissipated energy is
# within 0.6 % (intrinsic) and 2 % (extrinsic) of a run with a 4 times shorter step, and the
# extrinsic run blows up at 0.6 (the intrinsic one was still stable at 0.4).
DT_FACTOR = {"intrinsic": 0.2, "extrinsic": 0.25}


def write_mesh(path, length, width, size):
    """The bar's mesh (triangles of target size ``size``, m) as MSH 2.2, with physical
    groups left/right/bottom/top (1D tags 1-4) and concrete (2D tag 5)."""
    import gmsh
    gmsh.initialize(["-noenv"])
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.add("expanding-bar")
    gmsh.model.occ.addRectangle(0, 0, 0, length, width)
    gmsh.model.occ.synchronize()
    sides = {}
    for _, curve in gmsh.model.getEntities(1):
        x, y, _ = gmsh.model.occ.getCenterOfMass(1, curve)
        tol = 1e-9 * length
        name = ("left" if abs(x) < tol else "right" if abs(x - length) < tol
                else "bottom" if abs(y) < tol else "top")
        sides[name] = curve
    for tag, name in enumerate(("left", "right", "bottom", "top"), start=1):
        gmsh.model.setPhysicalName(1, gmsh.model.addPhysicalGroup(1, [sides[name]], tag), name)
    body = [tag for _, tag in gmsh.model.getEntities(2)]
    gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, body, 5), "concrete")
    gmsh.option.setNumber("Mesh.CharacteristicLengthMin", size)
    gmsh.option.setNumber("Mesh.CharacteristicLengthMax", size)
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
    gmsh.write(str(path))
    gmsh.finalize()


def run_dolfrag(mesh_path, overrides, out):
    """dolfrag's expanding-bar on the mesh file, serial, no fields or figures; returns its
    summary (wall_time_s: setup and time loop)."""
    from dataclasses import replace

    from mpi4py import MPI

    from dolfrag.case import Geometry, load_case
    from dolfrag.runner.driver import run
    case = load_case(CASE, [*overrides, "output.fields=0", "output.figures=false"])
    case = replace(case, geometry=Geometry(kind="file", file=Path(mesh_path).resolve(), dim=2))
    return run(case, out, quiet=True, comm=MPI.COMM_SELF)


# ------------------------------------------------------------------ the Akantu side
MATERIAL = """model solid_mechanics_model_cohesive [
  material elastic [
    name = concrete
    rho = {rho}
    E = {E}
    nu = {nu}
    Plane_Stress = {plane_stress}
  ]
  material {law} [
    name = cohesive
    sigma_c = {sigma_c}
    G_c = {G_c}
    beta = 1
    penalty = {penalty}{extra}
  ]
]
"""


def run_akantu(mesh_path, mode, p, out):
    """One Akantu run (in the Akantu venv): p holds the case's values (SI). Returns a dict:
    wall time (s), steps, dt (s), energies (J/m), fragment masses (kg/m)."""
    import akantu as aka
    import numpy as np
    out.mkdir(parents=True, exist_ok=True)
    # the intrinsic opening stiffness (Pa/m), also the penalty of Akantu's contact in closing
    # (both variants), so that a closing facet is no softer than an opening one
    stiffness = STIFFNESS_RATIO * p["E"] / p["size"]
    extra = f"\n    delta_0 = {p['sigma_c'] / stiffness!r}" if mode == "intrinsic" else ""
    material = out / f"material_{mode}.dat"
    material.write_text(MATERIAL.format(law="cohesive_bilinear" if mode == "intrinsic" else "cohesive_linear",
                                        penalty=stiffness, extra=extra, **p))
    start = time.perf_counter()
    aka.parseInput(str(material))
    mesh = aka.Mesh(2)
    mesh.read(str(mesh_path))
    model = aka.SolidMechanicsModelCohesive(mesh)
    model.initFull(_analysis_method=aka._explicit_lumped_mass, _is_extrinsic=mode == "extrinsic")
    if mode == "extrinsic":
        model.updateAutomaticInsertion()
    steps = math.ceil(p["end"] / (DT_FACTOR[mode] * model.getStableTimeStep()))
    dt = p["end"] / steps
    model.setTimeStep(dt)
    x = mesh.getNodes()[:, 0]
    lo, hi = x.min(), x.max()
    speed = p["strain_rate"] * (hi - lo) / 2
    velocity = model.getVelocity()
    velocity[:] = 0.0
    velocity[:, 0] = p["strain_rate"] * (x - (lo + hi) / 2)
    kinetic_0 = model.getEnergy("kinetic")
    ends, counted = None, -1
    for k in range(steps):
        # every copy of every node on x = 0 and x = L, found by its reference position:
        # Akantu's node groups miss some of the copies that cohesive insertion makes
        # (measured: 40 of the 61 copies at x = 0 after the intrinsic insertion)
        if mesh.getNbNodes() != counted:
            counted, x = mesh.getNbNodes(), mesh.getNodes()[:, 0]
            ends = [(np.flatnonzero(np.abs(x - at) < 1e-9 * (hi - lo)), sign) for at, sign in ((lo, -1.0), (hi, 1.0))]
        # blocked dofs are skipped by Akantu's predictor: the ends' displacement is set to
        # its value at the end of the step
        u, v, blocked = model.getDisplacement(), model.getVelocity(), model.getBlockedDOFs()
        for nodes, sign in ends:
            blocked[nodes, 0] = True
            u[nodes, 0] = sign * speed * (k + 1) * dt
            v[nodes, 0] = sign * speed
        if mode == "extrinsic":
            model.checkCohesiveStress()
        model.solveStep()
    wall = time.perf_counter() - start
    energies = {name: model.getEnergy(name) for name in ("kinetic", "potential", "dissipated", "reversible",
                                                         "contact")}
    manager = aka.FragmentManager(model)
    manager.computeAllData()
    mass = np.asarray(manager.getMass()).reshape(-1, 2)[:, 0]
    return {"mode": mode, "wall_time_s": wall, "steps": steps, "dt_s": dt, "kinetic_0_J": kinetic_0,
            "energies_J": energies, "fragment_mass_kg": mass.tolist()}


# ------------------------------------------------------------------ driver
def _case_values(overrides, size, end):
    from dolfrag.case import load_case
    case = load_case(CASE, overrides)
    mat, law = case.material, case.interface
    return {"E": mat.E, "nu": mat.nu, "rho": mat.rho, "plane_stress": str(mat.hypothesis == "plane_stress").lower(),
            "sigma_c": law.sigma_c, "G_c": law.G_c, "strain_rate": case.load.strain_rate, "size": size,
            "end": end, "length": case.geometry.length, "width": case.geometry.width}


def _count(masses, share):
    total = sum(masses)
    return sum(m >= share * total for m in masses)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=float, help="mesh size (m), default: the case's")
    parser.add_argument("--end", type=float, help="end time (s), default: the case's")
    parser.add_argument("--strain-rate", type=float, help="eps_dot (1/s), default: the case's")
    parser.add_argument("--akantu-python", default=str(ROOT / ".venv-akantu" / "bin" / "python"))
    parser.add_argument("--out", default=str(ROOT / "results" / "peer"))
    parser.add_argument("--akantu", nargs=3, metavar=("MODE", "MESH", "PARAMS"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.akantu:  # the Akantu side, in its own venv: one JSON line on stdout
        mode, mesh_path, params = args.akantu
        print(json.dumps(run_akantu(Path(mesh_path), mode, json.loads(params), Path(args.out))))
        return
    from dolfrag.case import load_case
    from dolfrag.post.expanding import MASS_SHARE
    overrides = [f"load.strain_rate={args.strain_rate!r}"] if args.strain_rate else []
    base = load_case(CASE, overrides)
    size, end = args.size or base.mesh.size, args.end or base.time.end
    overrides += [f"mesh.size={size!r}", f"time.end={end!r}"]
    p = _case_values(overrides, size, end)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    mesh_path = out / "bar.msh"
    write_mesh(mesh_path, p["length"], p["width"], size)
    ours = run_dolfrag(mesh_path, overrides, out / "dolfrag")
    peers = []
    for mode in ("intrinsic", "extrinsic"):
        done = subprocess.run([args.akantu_python, __file__, "--out", str(out / "akantu"), "--akantu", mode,
                               str(mesh_path), json.dumps(p)], capture_output=True, text=True, check=False)
        if done.returncode != 0:
            sys.exit(f"Akantu ({mode}) failed:\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}")
        peers.append(json.loads(done.stdout.strip().splitlines()[-1]))
    kinetic_0 = 0.5 * p["rho"] * p["width"] * p["strain_rate"] ** 2 * p["length"] ** 3 / 12
    block = ours["expanding_bar"]
    rows = [("dolfrag imex, linear_softening (rigid until sigma_c)", ours["wall_time_s"], ours["steps"], ours["dt_s"],
             block["fragments"], block["pieces"], ours["energies_J"]["D_damage_J"])]
    rows += [(f"Akantu {r['mode']} ({'cohesive_bilinear' if r['mode'] == 'intrinsic' else 'cohesive_linear'})",
              r["wall_time_s"], r["steps"], r["dt_s"], _count(r["fragment_mass_kg"], MASS_SHARE),
              len(r["fragment_mass_kg"]), r["energies_J"]["dissipated"]) for r in peers]
    cmd = " ".join(["python benchmarks/peer_akantu.py", *sys.argv[1:]])
    print(f"expanding bar: {ours['cells']} triangles (h = {size} m), eps_dot = {p['strain_rate']:g} 1/s, "
          f"sigma_c = {p['sigma_c']:g} Pa, G_c = {p['G_c']:g} J/m^2, end {end:g} s ({cmd})")
    print(f"initial kinetic energy (J/m): closed form {kinetic_0:.6g}, Akantu "
          + ", ".join(f"{r['mode']} {r['kinetic_0_J']:.6g}" for r in peers))
    print(f"| code | wall time (s) | steps | dt (s) | fragments (>= {MASS_SHARE:.0%} of the mass) | pieces "
          "| dissipated (J/m) |\n|---|---:|---:|---:|---:|---:|---:|")
    for name, wall, steps, dt, count, pieces, dissipated in rows:
        print(f"| {name} | {wall:.1f} | {steps} | {dt:.3g} | {count} | {pieces} | {dissipated:.4g} |")
    for r in peers:
        print(f"wall time dolfrag / Akantu {r['mode']}: {ours['wall_time_s'] / r['wall_time_s']:.3g}")
    (out / "peer.json").write_text(json.dumps({"dolfrag": ours, "akantu": peers, "params": p}, indent=1, default=str))


if __name__ == "__main__":
    main()
