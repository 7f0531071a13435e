"""Bar layers behind the named faces of a user's 3D mesh (geometry.kind = "file").

Each face group of ``rebar.faces`` (a physical surface group of the .geo/.msh, e.g. a
bunker's ``inner`` and ``outer``) is split into its flat patches (facets of one outward
normal and one plane). Behind each patch lie two layers, as in a generated box or bunker:
bars along each of two in-plane axes, ``rebar.spacing`` apart and centred on the patch, the
first layer at ``rebar.cover`` (face to bar axis) inward along the normal and the second
one diameter further in, so that they cross. The in-plane axes are the global axes
tangent to the patch when its normal is a global axis; otherwise the horizontal in-plane
direction (normal x z, or x on a horizontal patch) and the one across it. A bar runs
where its line, seen along the normal, crosses the patch, less ``rebar.cover`` at each
end: it stops with cover short of an opening's edge or the patch's border (a real bar
would be bent or lapped at a corner). Units: m, m^2.

The polylines are the same on every rank: the facets are gathered and sorted by
position first.
"""
import numpy as np

# Facets whose normals agree to this, and whose planes to this share of the mesh size, form one patch.
NORMAL_TOLERANCE = 1e-6
PLANE_TOLERANCE = 1e-6


def polylines(rebar, space, domain, comm):
    """Polylines (list of (2, 3) arrays) and steel areas (m^2) of the layers behind each
    face group of ``rebar.faces`` of a 3D file mesh (space: space.Space; domain:
    mesh.Domain). Collective."""
    lines = []
    for name in rebar.faces:
        triangles, normals = _gathered_facets(space, domain, name, comm)
        for patch, normal in _patches(triangles, normals, domain.size):
            lines.extend(_patch_bars(patch, normal, rebar.cover, rebar.diameter, rebar.spacing))
    return lines, np.full(len(lines), np.pi * rebar.diameter**2 / 4)


def _gathered_facets(space, domain, name, comm):
    """Corner coordinates (n, 3, 3) and outward normals (n, 3) of every facet of the face
    group ``name``, over all ranks, each once, sorted by centroid."""
    tag = domain.boundary_tag(name)
    _, verts = space.boundary_facets(domain.facet_tags, tag)
    every = comm.allgather((space.vertex_x[verts], space.boundary_normals(domain.facet_tags, tag)))
    triangles = np.concatenate([t for t, _ in every])
    normals = np.concatenate([n for _, n in every])
    key = np.round(triangles.mean(axis=1) / domain.size, 9)  # a facet on two ranks (ghosts) counts once
    _, first = np.unique(key, axis=0, return_index=True)
    return triangles[first], normals[first]


def _patches(triangles, normals, size):
    """(triangles, unit normal) of each flat patch: facets of one normal and one plane, in
    a deterministic order (by normal, then by plane)."""
    normal_key = np.round(normals / NORMAL_TOLERANCE).astype(np.int64)
    offset = np.einsum("ij,ij->i", normals, triangles[:, 0])
    key = np.column_stack([normal_key, np.round(offset / (PLANE_TOLERANCE * size)).astype(np.int64)])
    groups, which = np.unique(key, axis=0, return_inverse=True)
    for k in range(len(groups)):
        members = which.ravel() == k
        normal = normals[members].mean(axis=0)
        yield triangles[members], normal / np.linalg.norm(normal)


def in_plane_axes(normal):
    """Two orthonormal axes (2, 3) tangent to a plane of unit ``normal``: the tangent global
    axes (in x, y, z order) if the normal is a global axis; else the horizontal tangent
    (normal x z, or x for a horizontal plane) and the one across it."""
    along = np.flatnonzero(np.abs(np.abs(normal) - 1.0) < NORMAL_TOLERANCE)
    if len(along):
        return np.eye(3)[[a for a in range(3) if a != along[0]]]
    first = np.cross(normal, [0.0, 0.0, 1.0])
    first /= np.linalg.norm(first)
    return np.array([first, np.cross(normal, first)])


def _patch_bars(triangles, normal, cover, diameter, spacing):
    """The two layers of bars behind one flat patch (see the module docstring)."""
    axes = in_plane_axes(normal)
    c = np.mean(triangles.reshape(-1, 3) @ normal)  # the plane: x . normal = c
    flat = triangles @ axes.T  # (n, 3, 2): in-plane coordinates
    lines = []
    for layer in range(2):
        along, across = layer, 1 - layer
        depth = cover + layer * diameter
        low, high = flat[:, :, across].min(), flat[:, :, across].max()
        count = max(1, int(np.floor((high - low) / spacing + 1e-9)))  # 1e-9: a whole number of spacings
        for t in (low + high) / 2 + (np.arange(count) - (count - 1) / 2) * spacing:
            for s0, s1 in _crossing(flat[:, :, along], flat[:, :, across], t):
                if s1 - s0 > 2 * cover:
                    ends = np.array([s0 + cover, s1 - cover])
                    lines.append((c - depth) * normal + ends[:, None] * axes[along] + t * axes[across])
    return lines


def _crossing(s, t, level):
    """The merged intervals of s along which the line t = level crosses the triangles whose
    corners have in-plane coordinates (s, t) (n, 3)."""
    a, b = [0, 1, 2], [1, 2, 0]  # the three edges
    ta, tb, sa, sb = t[:, a], t[:, b], s[:, a], s[:, b]
    cut = ((ta - level) * (tb - level) <= 0) & (ta != tb)
    share = np.divide(level - ta, tb - ta, out=np.zeros_like(ta), where=cut)
    hit = np.where(cut, sa + share * (sb - sa), np.nan)
    crossed = cut.sum(axis=1) >= 2
    lows, highs = np.nanmin(hit[crossed], axis=1), np.nanmax(hit[crossed], axis=1)
    merged = []
    scale = max(np.ptp(s), 1e-300)
    for lo, hi in sorted(zip(lows, highs)):
        if merged and lo <= merged[-1][1] + 1e-9 * scale:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    return merged
