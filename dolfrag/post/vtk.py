"""ParaView files of DG-P1 fields: a time series (.pvd) of partitioned grids (.pvtu), one
piece (.vtu) per rank holding only the cells that rank owns, so that every cell of the mesh
appears exactly once (the halo cells each rank also holds are left out).

Every cell keeps its own copy of each vertex, as the DG space does, so the crack openings
show. Vectors are written with 3 components (z = 0 in 2D), as ParaView's filters expect.
The .pvd index is rewritten after each snapshot (write then rename): it lists complete
snapshots only, whenever the run stops.
"""
import os
import sys
from pathlib import Path

import numpy as np

from dolfrag import compat

CELL_TYPES = {2: 5, 3: 10}  # VTK_TRIANGLE, VTK_TETRA
BYTE_ORDER = "LittleEndian" if sys.byteorder == "little" else "BigEndian"  # of the raw arrays written


def _owned_cell_values(f):
    """(n_owned_cells * dofs per cell, components) values of the DG-P1 Function f, cell
    by cell in each cell's local dof order; vectors padded to 3 components."""
    V = f.function_space
    dofs = compat.cell_dofs(V)[:V.mesh.topology.index_map(V.mesh.topology.dim).size_local].ravel()
    bs = V.dofmap.index_map_bs
    values = f.x.array.reshape(-1, bs)[dofs]
    return np.pad(values, ((0, 0), (0, 3 - bs))) if bs > 1 else values


def _data_array(name, values, offset, kind="Float64"):
    components = values.shape[1] if values.ndim == 2 else 1
    label = f' Name="{name}"' if name else ""
    return f'<DataArray type="{kind}"{label} NumberOfComponents="{components}" format="appended" offset="{offset}"/>'


def write_piece(path, functions):
    """One .vtu of this rank's owned cells: their DG vertex copies as points, the Functions
    (DG-P1, on the same mesh) as point data. Returns [(name, components)] of the fields."""
    V = functions[0].function_space
    msh = V.mesh
    tdim = msh.topology.dim
    n_cells = msh.topology.index_map(tdim).size_local
    per_cell = tdim + 1
    dofs = compat.cell_dofs(V)[:n_cells].ravel()
    points = V.tabulate_dof_coordinates()[dofs]
    arrays = [(f.name, _owned_cell_values(f).astype(np.float64)) for f in functions]
    blocks, offset = [], 0

    def add(values):
        nonlocal offset
        data = np.ascontiguousarray(values).tobytes()
        blocks.append(np.uint64(len(data)).tobytes() + data)
        start, offset = offset, offset + 8 + len(data)
        return start

    point_data = "".join(_data_array(name, values, add(values)) for name, values in arrays)
    points_xml = f'<Points>{_data_array("", points, add(points.astype(np.float64)))}</Points>'
    connectivity = np.arange(n_cells * per_cell, dtype=np.int64)
    offsets = np.arange(1, n_cells + 1, dtype=np.int64) * per_cell
    types = np.full(n_cells, CELL_TYPES[tdim], dtype=np.uint8)
    cells = "".join(_data_array(name, values, add(values), kind)
                    for name, values, kind in (("connectivity", connectivity, "Int64"),
                                               ("offsets", offsets, "Int64"), ("types", types, "UInt8")))
    xml = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
           f'byte_order="{BYTE_ORDER}" header_type="UInt64">\n<UnstructuredGrid>\n'
           f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{n_cells}">\n'
           f'<PointData>{point_data}</PointData>\n{points_xml}\n<Cells>{cells}</Cells>\n'
           '</Piece>\n</UnstructuredGrid>\n<AppendedData encoding="raw">\n_')
    with open(path, "wb") as out:
        out.write(xml.encode())
        out.write(b"".join(blocks))
        out.write(b"\n</AppendedData>\n</VTKFile>\n")
    return [(name, values.shape[1] if values.ndim == 2 else 1) for name, values in arrays]


def _replace(path, text):
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


class FieldsFile:
    """``path`` (.pvd) and its snapshots ``<stem>NNNNNN.pvtu`` / ``<stem>_p<rank>_NNNNNN.vtu``
    beside it. ``write_function(functions, t)`` adds a snapshot at time t (s); collective."""
    STATE = ("times",)  # what a checkpoint keeps: a resumed run continues the series

    def __init__(self, comm, path):
        self.comm, self.path, self.times = comm, Path(path), []

    def write_function(self, functions, t):
        stem, k = self.path.stem, len(self.times)
        piece = f"{stem}_p{{}}_{k:06d}.vtu"
        fields = write_piece(self.path.with_name(piece.format(self.comm.rank)), functions)
        self.comm.barrier()  # every piece is complete before the index names it
        self.times.append(t)
        if self.comm.rank != 0:
            return
        arrays = "".join(f'<PDataArray type="Float64" Name="{name}" NumberOfComponents="{n}"/>'
                         for name, n in fields)
        pieces = "".join(f'<Piece Source="{piece.format(r)}"/>\n' for r in range(self.comm.size))
        _replace(self.path.with_name(f"{stem}{k:06d}.pvtu"),
                 '<?xml version="1.0"?>\n<VTKFile type="PUnstructuredGrid" version="1.0" '
                 f'byte_order="{BYTE_ORDER}" header_type="UInt64">\n<PUnstructuredGrid GhostLevel="0">\n'
                 f'<PPointData>{arrays}</PPointData>\n'
                 '<PPoints><PDataArray type="Float64" NumberOfComponents="3"/></PPoints>\n'
                 f'{pieces}</PUnstructuredGrid>\n</VTKFile>\n')
        self.write_index()

    def write_index(self):
        """The .pvd listing the snapshots in ``times`` (rank 0 writes)."""
        if self.comm.rank != 0:
            return
        stem = self.path.stem
        steps = "".join(f'<DataSet timestep="{float(time)!r}" part="0" file="{stem}{i:06d}.pvtu"/>\n'
                        for i, time in enumerate(self.times))
        _replace(self.path, '<?xml version="1.0"?>\n<VTKFile type="Collection" version="1.0">\n'
                            f'<Collection>\n{steps}</Collection>\n</VTKFile>\n')
