"""What the field figures show (post/figures.py), read back from the drawn pyvista actors:
axes in m at round ticks, a titled colour bar over a meaningful range (an intact run's
damage 0 ... 1), and a caption with the case and the time in the one convention (ms)
that every figure writes. A few seconds: small meshes and one short wall run."""
import re

import numpy as np
import pytest
from mpi4py import MPI

import dolfrag  # noqa: F401  (loads VTK before DOLFINx: the other order aborts on a colour bar)
from conftest import box, rectangle
from dolfrag import mesh, space as spaces
from dolfrag.case import load_case
from dolfrag.post.figures import (DAMAGE_RANGE, SIGNED, broken_mesh_png, colour_range, figure_title, milliseconds,
                                  round_axis, tick_steps)
from dolfrag.runner import final
from dolfrag.runner.driver import run


def test_a_time_is_written_in_ms_to_three_significant_digits():
    assert [milliseconds(t) for t in (6e-3, 2e-4, 8e-5, 5e-6, 0.125, 1.5, 0.0)] == \
        ["6.00 ms", "0.200 ms", "0.0800 ms", "0.00500 ms", "125 ms", "1500 ms", "0.00 ms"]
    assert figure_title("bunker-h2", 6e-3) == "bunker-h2, t = 6.00 ms"


def test_axis_limits_are_round_multiples_of_a_round_step():
    # a wall 0.12 m thick, displaced by a few nanometres: no extra step for them
    assert round_axis(-2.3e-9, 0.1200001, 0.02) == pytest.approx((0.0, 0.12, 7))
    assert round_axis(-0.013, 1.02, 0.2) == pytest.approx((-0.2, 1.2, 8))
    # a thin slab's thickness is ticked no finer than a tenth of its largest span
    assert tick_steps([1.0, 1.0, 0.2]) == pytest.approx([0.2, 0.2, 0.1])
    assert tick_steps([0.5, 0.12]) == pytest.approx([0.1, 0.05])


def test_the_colour_range_is_damages_0_to_1_a_components_symmetric_else_from_0():
    intact = np.zeros(10)
    assert colour_range(intact, DAMAGE_RANGE) == (0.0, 1.0)
    assert colour_range(np.array([-0.2, 0.5]), SIGNED) == (-0.5, 0.5)
    assert colour_range(np.array([0.1, 0.3]), None) == (0.0, 0.3)
    assert colour_range(intact, None) == (0.0, 1.0)  # never 0 ... 0


def is_round_ticks(labels):
    """Labels as written (no exponent, no long decimals) of equally spaced values, the step
    1, 2, 2.5 or 5 x 10^k, every value a multiple of it. In 3D an end label may be blank
    (deliberately: left out where two axes meet at a corner), the ticks between all written."""
    if labels and labels[0] == "":
        labels = labels[1:]
    if labels and labels[-1] == "":
        labels = labels[:-1]
    values = np.array([float(x) for x in labels])
    step = np.diff(values)
    mantissa = step[0] / 10.0 ** np.floor(np.log10(step[0]) + 1e-9)
    return (len(values) >= 2 and all(re.fullmatch(r"-?\d+(\.\d{1,3})?", x) for x in labels)
            and np.allclose(step, step[0]) and np.isclose(mantissa, [1, 2, 2.5, 5]).any()
            and np.allclose(values / step[0], np.round(values / step[0])))


@pytest.fixture(scope="module", params=[2, 3])
def body(request):
    """(space, displacement) of a 2D wall section 1 x 0.12 m or a 3D slab 1 x 1 x 0.2 m."""
    geometry, size = (rectangle(1.0, 0.12), 0.04) if request.param == 2 else (box(1.0, 1.0, 0.2), 0.1)
    space = spaces.create(mesh.build(geometry, size, MPI.COMM_SELF))
    import dolfinx.fem as fem
    u = fem.Function(space.V)
    u.x.array[:] = 1e-6 * np.sin(np.arange(len(u.x.array)))
    return space, u


def test_a_damage_figure_has_round_axes_a_0_to_1_bar_and_the_case_and_time(body, tmp_path):
    space, u = body
    path = tmp_path / "damage.png"
    damage = np.where(space.x[:, 0] < 0.1, 0.3, 0.0)  # a little damage: the bar still reads 0 ... 1
    drawn = broken_mesh_png(space, u, damage, path, "damage 1 - beta (-)",
                            figure_title("demo-case", 2e-4), clim=DAMAGE_RANGE)
    assert path.stat().st_size > 10_000
    assert drawn["colour_bar"] == ("damage 1 - beta (-)", 0.0, 1.0)
    assert drawn["caption"].splitlines()[0] == "demo-case, t = 0.200 ms"
    axes = ["x (m)", "y (m)", "z (m)"][:space.gdim]
    assert list(drawn["axes"]) == axes
    for title in axes:
        assert is_round_ticks(drawn["axes"][title]), (title, drawn["axes"][title])


def test_a_velocity_components_figure_has_axes_and_a_symmetric_bar(body, tmp_path):
    space, u = body
    drawn = broken_mesh_png(space, u, space.x[:, 0] - 0.3, tmp_path / "velocity_x.png", "velocity v_x (m/s)",
                            figure_title("demo-case", 2e-4), scale=1.0, clim=SIGNED, note="moved apart")
    assert drawn["colour_bar"] == pytest.approx(("velocity v_x (m/s)", -0.7, 0.7))
    assert drawn["caption"] == "demo-case, t = 0.200 ms\ndisplacement x 1; moved apart"
    assert all(is_round_ticks(labels) for labels in drawn["axes"].values()) and "x (m)" in drawn["axes"]


def test_a_runs_field_figures_carry_its_case_and_time_and_an_intact_damage_bar_reads_0_to_1(tmp_path, monkeypatch):
    """The common figures of a short, intact wall run, as broken_mesh_png drew them."""
    drawn = {}

    def recorded(space, u, values, path, *args, **kwargs):
        drawn[path.name] = broken_mesh_png(space, u, values, path, *args, **kwargs)

    monkeypatch.setattr(final, "broken_mesh_png", recorded)
    summary = run(load_case("wall-bending-clamped", ["time.end=2e-5", "output.fields=0"]), tmp_path, quiet=True,
                  comm=MPI.COMM_SELF)
    assert summary["broken_links"] == 0
    assert set(drawn) == {"velocity.png", "velocity_x.png", "damage.png", "fragments.png"}
    for name, contents in drawn.items():
        assert contents["caption"].startswith("wall-bending-clamped, t = 0.0200 ms\n"), name
        assert set(contents["axes"]) == {"x (m)", "y (m)"}, name
    assert drawn["damage.png"]["colour_bar"] == ("damage 1 - beta (-)", 0.0, 1.0)
    lo, hi = drawn["velocity_x.png"]["colour_bar"][1:]
    assert lo == -hi and hi > 0
