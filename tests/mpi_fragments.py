"""Under mpirun: fragments of the rectangle cut at mid-length and at its quarters, with one
link of the cut facets holding, and held only by facets split between ranks (rank 0 saves)."""
import sys

import numpy as np
from mpi4py import MPI

from dolfrag.post.fragments import fragments
from test_fragments import LENGTH, assemble, band_fields, cut, hold_one_link, plane_break_times

comm = MPI.COMM_WORLD
space, links, mass = assemble(comm)
results = {}
for name, planes in (("half", [LENGTH / 2]), ("chain", [LENGTH / 4, LENGTH / 2, 3 * LENGTH / 4])):
    v, u = band_fields(space, planes)
    times = plane_break_times(space, links, planes, 1e-6 * np.arange(1, len(planes) + 1), 0.5e-6)
    frags = fragments(space, links, cut(space, links, planes), mass, v, displacement=u, break_time=times)
    results.update({f"{name}_{key}": np.asarray(value) for key, value in vars(frags).items()})
    assert len(set(comm.allgather(frags.centroid.tobytes()))) == 1, "ranks disagree"
broken = cut(space, links, [LENGTH / 2])
held = hold_one_link(space, links, broken)
results["held_count"] = len(fragments(space, links, held, mass, np.zeros_like(mass)))

# Facets whose two links sit on different ranks (none on 1 rank) are the only ones holding,
# by both links or by one only: the fragments are the same only if the flags of the two
# ranks are ORed. The rank boundary moves between runs (measured), so no cut plane is used.
tdim = space.gdim
f2c = space.mesh.topology.connectivity(tdim - 1, tdim)
local = f2c.array[f2c.offsets[links.facet][:, None] + np.arange(2)]
cells = space.mesh.topology.index_map(tdim).local_to_global(local.ravel())
key = np.sort(cells.reshape(-1, 2), axis=1) @ np.array([1, 1 << 31])
everyone, counts = np.unique(np.concatenate(comm.allgather(np.unique(key))), return_counts=True)
shared = np.isin(key, everyone[counts > 1])
one = np.where(shared, hold_one_link(space, links, np.ones(len(links), bool)), True)
results["shared_both"] = len(fragments(space, links, ~shared, mass, np.zeros_like(mass)))
results["shared_one"] = len(fragments(space, links, one, mass, np.zeros_like(mass)))
results["n_shared"] = comm.allreduce(np.count_nonzero(shared))
if comm.rank == 0:
    np.savez(sys.argv[1], **results)
