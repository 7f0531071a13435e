"""fields.pvd read back with pyvista (VTK's own readers): every cell of the mesh once, the
area or volume of the body, and the same fields on 1 and 2 ranks."""
import json

import numpy as np
import pytest
import pyvista as pv

from conftest import mpirun

SHORT = ["time.end=4e-6", "output.fields=2", "output.figures=false"]
CASES = {"rectangle": ("sound-bar", ["mesh.size=0.005"], 0.12 * 0.04),
         "box": ("slab-3d-scabbing", ["geometry.length=0.2", "geometry.width=0.2", "mesh.size=0.04",
                                      "load.region_min=", "load.region_max=", "load.region_factor="], 0.2 * 0.2 * 0.1)}


def last_snapshot(out):
    reader = pv.get_reader(str(out / "fields.pvd"))
    assert len(reader.time_values) == 3  # t = 0 and the 2 snapshots
    reader.set_active_time_value(reader.time_values[-1])
    grid = reader.read()
    assert grid.n_blocks == 1
    return grid[0], json.loads((out / "summary.json").read_text())


def fragments_grid(out):
    """fragments.pvd's one snapshot (pyvista), and the time it was written at."""
    reader = pv.get_reader(str(out / "fragments.pvd"))
    assert len(reader.time_values) == 1
    grid = reader.read()
    assert grid.n_blocks == 1
    return grid[0], reader.time_values[0]


def cell_means(grid, name):
    """(sorted by centroid) cell centroids and the cell mean of a point field."""
    cells = grid.cells_dict
    (kind, conn), = cells.items()
    centroid = grid.points[conn].mean(axis=1)
    mean = grid.point_data[name][conn].mean(axis=1)
    order = np.lexsort(np.round(centroid, 9).T[::-1])
    return centroid[order], mean[order]


@pytest.mark.slow
@pytest.mark.parametrize("shape", sorted(CASES))
def test_fields_pvd_has_each_cell_once_on_1_and_2_ranks(shape, tmp_path):
    name, sets, measure = CASES[shape]
    grids = {}
    for ranks in (1, 2):
        out = tmp_path / f"n{ranks}"
        mpirun(["-m", "dolfrag.cli", "run", name, "--out", out, "--quiet",
                *(x for s in sets + SHORT for x in ("--set", s))], n=ranks)
        grid, summary = last_snapshot(out)
        assert summary["ranks"] == ranks
        assert grid.n_cells == summary["cells"]
        sizes = grid.compute_cell_sizes(length=False, area=shape == "rectangle", volume=shape == "box")
        size = np.abs(sizes.cell_data["Area" if shape == "rectangle" else "Volume"])
        # the cells tile the body once: its area / volume to round-off
        assert size.sum() == pytest.approx(measure, rel=1e-12)
        assert set(grid.point_data.keys()) >= {"displacement", "velocity", "damage"}
        grids[ranks] = grid
    c1, v1 = cell_means(grids[1], "velocity")
    c2, v2 = cell_means(grids[2], "velocity")
    np.testing.assert_allclose(c2, c1, atol=1e-12)  # the same cells, each once
    assert np.abs(v1).max() > 0  # the pulse has entered
    # the same velocities cell by cell: the step is rank-independent to solver round-off
    np.testing.assert_allclose(v2, v1, rtol=0, atol=1e-9 * np.abs(v1).max())
