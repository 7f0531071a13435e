"""Under mpirun -n 2: a built-in case run with an imposed partition (mesh.build's owner_rule):
stripes across x, of width W, alternately on ranks 0 and 1 (by cell centroid), or, with
"random:SEED", each cell on a rank drawn at random (a partition no graph partitioner would
give: many small pieces, stars split everywhere).

argv: case, output directory, W (m) or random:SEED, then "section.key=value" overrides. Besides the run's
own outputs, rank 0 writes
partition.json: the number of vertex stars split between ranks (a star is split when the
owner of its vertex holds one of its cells as a ghost, i.e. another rank owns that cell)
and how many of the broken links sit in split stars (links.csv rows matched by vertex
position).
"""
import json
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI
from scipy.spatial import cKDTree

import dolfrag
from dolfrag import mesh, space as spaces
from dolfrag.case import load_case

case_name, out, rule = sys.argv[1], sys.argv[2], sys.argv[3]
overrides = sys.argv[4:]


def owner_rule(centroids):
    if rule.startswith("random:"):
        return np.random.default_rng(int(rule[7:])).integers(0, 2, len(centroids))
    return np.floor(centroids[:, 0] / float(rule)).astype(int) % 2


domains = []
build = mesh.build


def build_by_rule(geometry, size, comm, owner_rule_given=None, **kwargs):  # the run calls mesh.build: give it the rule
    if comm.size == 1:  # a serial copy (homogenise.bar_modulus's static push): nothing to partition
        return build(geometry, size, comm, **kwargs)
    domains.append(build(geometry, size, comm, owner_rule=owner_rule, **kwargs))
    return domains[-1]


mesh.build = build_by_rule
comm = MPI.COMM_WORLD
dolfrag.run(load_case(case_name, overrides), out, quiet=True, comm=comm)

topology = domains[0].mesh.topology
tdim = topology.dim
n_owned_vertices = topology.index_map(0).size_local
v2c = topology.connectivity(0, tdim)
ghost_cell = v2c.array >= topology.index_map(tdim).size_local
split = np.add.reduceat(ghost_cell, v2c.offsets[:-1])[:n_owned_vertices] > 0
split_x = comm.gather(spaces.create(domains[0]).vertex_x[:n_owned_vertices][split], root=0)
if comm.rank == 0:
    split_x = np.concatenate(split_x)
    table = np.genfromtxt(Path(out) / "links.csv", delimiter=",", names=True)
    broken = table["broken"] > 0
    broken_x = np.column_stack([table[a][broken] for a in "xyz"[:tdim]])
    # links.csv keeps 9 digits (1e-10 m on these < 1 m bodies); vertices are >= 1 mm apart
    distance = cKDTree(split_x).query(broken_x)[0] if len(split_x) else np.full(len(broken_x), np.inf)
    at_split = np.count_nonzero(distance < 1e-8)
    (Path(out) / "partition.json").write_text(json.dumps({
        "split_stars": len(split_x), "broken_links": int(broken.sum()),
        "broken_links_at_split_stars": int(at_split)}))
