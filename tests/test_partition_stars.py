"""Vertex stars split by the partition (docs/method.md, "Parallel layout"): cracks that run exactly along
partition boundaries give the fragments and energies of one rank.

The partition is imposed (mesh.build's owner_rule, through tests/mpi_partition.py) on
the structured spall bar, whose vertical grid lines are facets: stripes one cell column
wide, alternately on ranks 0 and 1, so that every vertical grid line inside the bar is a
partition boundary and the star of every vertex on it is split between the two ranks
(its owner holds the cells on the other side as ghosts). The reflected pulse breaks the
bar along vertical grid lines, i.e. exactly along partition boundaries: every broken
link lies in a split star, and the star solve of its vertex needs the ghost cells'
displacements, which only the one ghost update per step brings.
"""
import json

import numpy as np
import pytest
from mpi4py import MPI

import dolfrag
from conftest import mpirun
from dolfrag.case import load_case

# spall-bar shortened to 0.12 m and widened to 0.05 m (20 cells: 21 vertices per grid
# line), with a 30 us pulse: 14 spall planes 2.5 mm apart break between 49 and 54 us
# (measured), each a whole vertical grid line of 40 links
SPALL = ["geometry.length=0.12", "geometry.width=0.05", "load.duration=30e-6", "time.end=55e-6",
         "output.fields=0", "output.figures=false"]
STRIPE = 0.0025  # m: one cell column, the mesh size


def history(path):
    return np.genfromtxt(path / "history.csv", delimiter=",", names=True)


@pytest.mark.mpi
def test_cracks_along_partition_boundaries_give_the_one_rank_fragments_and_energies(tmp_path):
    one = dolfrag.run(load_case("spall-bar", SPALL), tmp_path / "one", quiet=True, comm=MPI.COMM_SELF)
    mpirun(["tests/mpi_partition.py", "spall-bar", tmp_path / "two", STRIPE, *SPALL])
    two = json.loads((tmp_path / "two" / "summary.json").read_text())
    split = json.loads((tmp_path / "two" / "partition.json").read_text())
    # the partition is what the test claims: the 47 inner grid lines x 21 vertices are
    # split stars, and every broken link (hundreds) is in one of them
    assert split["split_stars"] >= 47 * 21
    assert split["broken_links"] == one["broken_links"] > 200
    assert split["broken_links_at_split_stars"] == split["broken_links"]
    # the same links broken at the same steps (positions and times to links.csv's 9 digits)
    tables = [np.genfromtxt(tmp_path / r / "links.csv", delimiter=",", names=True) for r in ("one", "two")]
    order = [np.lexsort((t["weight"], t["ny"], t["nx"], t["y"], t["x"])) for t in tables]
    for name in ("x", "y", "broken", "break_time_s"):
        assert np.allclose(tables[0][name][order[0]], tables[1][name][order[1]], rtol=1e-8, equal_nan=True), name
    frags_one, frags_two = one["fragments"], two["fragments"]
    assert frags_one["count"] == frags_two["count"] > 5
    for key in ("mass", "centroid"):  # the same pieces, summed in another order: round-off
        assert np.allclose(frags_one[key], frags_two[key], rtol=1e-8, atol=1e-12), key
    # each star stops at 1e-10 of the step's force scale (semismooth.FLOOR): velocities
    # agree to 1e-10 of the fastest piece; 1e-8 leaves room (test_nonsmooth.py)
    speed = np.abs(frags_one["velocity"]).max()
    assert np.allclose(frags_one["velocity"], frags_two["velocity"], rtol=0, atol=1e-8 * speed)
    h_one, h_two = history(tmp_path / "one"), history(tmp_path / "two")
    work = h_one["W_external_J"].max()
    for name in ("E_kinetic_J", "E_bulk_J", "E_interface_J", "D_damage_J", "D_contact_J", "balance_error_J"):
        # star problems solved to 1e-10 of their residual scale on both layouts
        assert np.allclose(h_one[name], h_two[name], rtol=0, atol=1e-6 * work), name
