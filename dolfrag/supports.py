"""Supports: boundaries whose displacement components stay zero.

A roller fixes the normal component, so its boundary must be a plane normal to an
axis (every builder boundary is); a clamped boundary fixes every component; a simple
support fixes the component along the last axis (y in 2D, z in 3D: the thickness of a
wall or slab), so the section turns and slides freely about it.
"""
import numpy as np
from mpi4py import MPI

from dolfrag.case import CaseError


def constrained_components(space, domain, supports):
    """Flat local dof components (owned and ghost) fixed by the case's supports. Collective."""
    comm = space.mesh.comm
    fixed = []
    for name in supports.clamped:
        fixed.append(space.components(space.boundary_dofs(domain.facet_tags, domain.boundary_tag(name))[:, None]).ravel())
    for name in supports.rollers:
        tag = domain.boundary_tag(name)
        n = space.boundary_normals(domain.facet_tags, tag)
        axes = comm.allgather(np.unique(np.argmax(np.abs(n), axis=1)) if len(n) else np.empty(0, int))
        axes = np.unique(np.concatenate(axes))
        flat = comm.allreduce(np.abs(np.abs(n).max(axis=1) - 1).max(initial=0.0), op=MPI.MAX) < 1e-9
        if len(axes) != 1 or not flat:
            raise CaseError(f"supports.rollers: boundary {name!r} is not a plane normal to an axis; "
                            "rollers need one (use clamped, or split the boundary)")
        fixed.append(space.gdim * space.boundary_dofs(domain.facet_tags, tag) + axes[0])
    for name in supports.simple:
        fixed.append(space.gdim * space.boundary_dofs(domain.facet_tags, domain.boundary_tag(name)) + space.gdim - 1)
    return np.unique(np.concatenate(fixed)) if fixed else np.empty(0, dtype=np.int64)
