"""validation/convergence.py: a study keeps its runs apart by end time, and tabulates what
they measured (here on a run's files written by hand, so that nothing is run)."""
import json
import subprocess
import sys

from conftest import ROOT

SCRIPT = ROOT / "validation" / "convergence.py"


def _fake_run(out, end, h=0.1):
    folder = out / "panel" / f"linear_softening-h{h:g}"
    folder.mkdir(parents=True)
    summary = {"status": "completed", "cells": 6955, "ranks": 2, "wall_time_s": 173.0,
               "case": {"time": {"end": end}},
               "energies_J": {"D_damage_J": 100.0, "D_contact_J": 55.0},
               "wall": {"midspan_deflection": {"peak_m": 9.8e-4}},
               "debris": {"hazard_distance_m": 0.0}}
    (folder / "summary.json").write_text(json.dumps(summary))
    (folder / "links.csv").write_text("broken,break_time_s,weight,damage\n1,0.00767,0.226,1\n0,nan,0.1,0.25\n")
    (folder / "history.csv").write_text("step,time_s,w_midspan_m,D_damage_J,D_contact_J,broken_links\n"
                                        "10,0.0059,-2.0e-4,1.0,0.0,0\n20,0.0081,-8.0e-4,90.0,10.0,27\n")
    return folder


def _study(out, *args):
    return subprocess.run([sys.executable, str(SCRIPT), "panel", "--sizes", "0.1", "--laws", "linear_softening",
                           "--out", str(out), *args], capture_output=True, text=True, timeout=60)


def test_a_run_of_another_end_is_refused_not_reused(tmp_path):
    _fake_run(tmp_path, 0.0085)
    result = _study(tmp_path, "--end", "0.02")
    assert result.returncode == 2, result.stderr
    line, = result.stderr.strip().splitlines()
    assert "0.0085" in line and "0.02" in line and "--out" in line


def test_the_table_reads_each_run_and_its_end(tmp_path):
    _fake_run(tmp_path, 0.0085)
    result = _study(tmp_path, "--table-only")
    assert result.returncode == 0, result.stderr
    assert "to 0.0085 s" in result.stdout  # the runs' end, not the study's default 0.02 s
    row = next(line for line in result.stdout.splitlines() if line.startswith("| 0.1 |"))
    # first crack 7.67 ms, peak deflection 0.98 mm, D_damage + D_contact, the broken facets'
    # area, the effective crack 0.226 x 1 + 0.1 x 0.25
    assert "| 7.67 | 0.98 | 155 | 0.226 | 0.251 |" in row


def test_the_state_at_given_times_comes_from_the_nearest_history_row(tmp_path):
    _fake_run(tmp_path, 0.0085)
    result = _study(tmp_path, "--table-only", "--at", "0.006", "0.008")
    assert result.returncode == 0, result.stderr
    row = [line for line in result.stdout.splitlines() if line.startswith("| 0.1 |")][-1]
    # |w| in mm, D_damage + D_contact, broken links, at the rows of 5.9 and 8.1 ms
    assert row == "| 0.1 | 0.200, 1, 0 | 0.800, 100, 27 |"


def test_a_run_still_going_is_read_from_its_history(tmp_path):
    # a run that has written history rows but neither its summary nor a checkpoint yet: no
    # row in the table, its state at the times asked from its history
    folder = _fake_run(tmp_path, 0.0085)
    (folder / "summary.json").unlink()
    result = _study(tmp_path, "--table-only", "--at", "0.008", "0.0125")
    assert result.returncode == 0, result.stderr
    assert "fewer than two completed meshes" in result.stdout
    # 12.5 ms lies past the last row (8.1 ms) by more than the rows' spacing (2.2 ms)
    assert result.stdout.splitlines()[-1] == "| 0.1 | 0.800, 100, 27 | – |"
    # a run that has written its history's header only
    (folder / "history.csv").write_text("step,time_s,w_midspan_m,D_damage_J,D_contact_J,broken_links\n")
    result = _study(tmp_path, "--table-only", "--at", "0.008")
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[-1] == "| 0.1 | – |"


def test_a_run_killed_before_its_summary_is_resumed_not_overwritten(tmp_path):
    # a launcher's SIGKILL during the final checkpoint leaves the last checkpoint and no
    # summary.json: the study must count that run as interrupted (its checkpoint's case and
    # ranks), not start it again with --overwrite. Shown by the end check, which reads the
    # checkpoint's case: asked for another end, the study refuses instead of running.
    import pickle

    from dolfrag.case import load_case
    from dolfrag.runner import checkpoint
    folder = tmp_path / "panel" / "linear_softening-h0.1" / checkpoint.FOLDER
    folder.mkdir(parents=True)
    (folder / checkpoint.CASE).write_bytes(pickle.dumps(load_case("bunker-wall-panel", ["time.end=0.0085"])))
    (folder / "rank00000-of-00002.pkl").write_bytes(b"")
    result = _study(tmp_path, "--end", "0.02")
    assert result.returncode == 2, result.stderr
    assert "0.0085" in result.stderr and folder.is_dir()


def test_the_bunker_study_reads_its_long_wall(tmp_path):
    """The bunker's deflection is its long wall's (summary.json: bunker.long_wall; history.csv:
    w_long_wall_m), and its table has the 3D columns (median piece, hazard distance)."""
    folder = tmp_path / "bunker" / "linear_softening-h0.2"
    folder.mkdir(parents=True)
    summary = {"status": "completed", "cells": 6248, "ranks": 2, "wall_time_s": 30.0,
               "case": {"time": {"end": 0.02}}, "energies_J": {"D_damage_J": 5300.0, "D_contact_J": 2800.0},
               "bunker": {"long_wall": {"peak_deflection_m": 0.0355}}, "debris": {"hazard_distance_m": 3.0}}
    (folder / "summary.json").write_text(json.dumps(summary))
    (folder / "links.csv").write_text("broken,break_time_s,weight,damage\n1,0.0066,0.02,1\n")
    # its history gives the long wall's deflection, not a midspan's
    (folder / "history.csv").write_text("time_s,w_long_wall_m,D_damage_J,D_contact_J,broken_links\n"
                                        "0.01,-0.0057,4000,100,9000\n0.02,-0.0355,5300,2800,30000\n")
    result = subprocess.run([sys.executable, str(SCRIPT), "bunker", "--sizes", "0.2", "--laws", "linear_softening",
                             "--out", str(tmp_path), "--table-only", "--at", "0.01"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    row = next(line for line in result.stdout.splitlines() if line.startswith("| 0.2 |"))
    assert "| 6.60 | 35.50 | 8100 |" in row and row.endswith("| 3.0 | 30 |")
    at = [line for line in result.stdout.splitlines() if line.startswith("| 0.2 |")][-1]
    assert at == "| 0.2 | 5.700, 4100, 9,000 |"
