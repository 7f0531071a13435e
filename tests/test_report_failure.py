"""A report that raises after the time loop does not lose the run: summary.json is written
with status "report_failed" naming it, the other reports and outputs are made, the command
exits 1 with one line, and `dolfrag report DIR` makes the reports again from the last
checkpoint, without recomputing the loop."""
import json
import os
import signal

import pytest

from dolfrag import cli
from dolfrag.runner import driver
from dolfrag.runner.reports.wall import WallReport

pytestmark = pytest.mark.slow  # whole runs of cases, seconds each: not in `make check`

# the wall section, 11 steps of the built-in case (about a second)
WALL = ["run", "wall-bending-clamped", "--quiet", "--set", "time.end=2e-5", "--set", "output.fields=1"]


def broken_summarise(self, summary, final):
    raise RuntimeError("a report made to fail")


def summary_of(folder):
    return json.loads((folder / "summary.json").read_text())


@pytest.fixture
def failed_run(tmp_path, monkeypatch, capsys):
    """A wall run whose wall report raised; (folder, its stderr)."""
    out = tmp_path / "r"
    with monkeypatch.context() as patch:
        patch.setattr(WallReport, "summarise", broken_summarise)
        assert cli.main([*WALL, "--out", str(out)]) == 1
    return out, capsys.readouterr().err


def test_a_failed_report_keeps_the_summary_and_the_other_outputs(failed_run):
    out, err = failed_run
    summary = summary_of(out)
    assert summary["status"] == "report_failed"
    # first the failure itself; the wall report's figures, which read its summary block, fail after it
    assert summary["report_errors"][0] == "WallReport.summarise: RuntimeError: a report made to fail"
    assert all(error.startswith("WallReport.") for error in summary["report_errors"])
    assert summary["steps_done"] == summary["steps"] == 11
    assert "energies_J" in summary and "fragments" in summary and "wall" not in summary
    for name in ("history.csv", "links.csv", "fragments.csv", "figures/damage.png", "figures/fragment_masses.png"):
        assert (out / name).is_file(), name  # the other reports and figures still ran
    assert list((out / "checkpoint").glob("rank*.pkl"))
    assert "Traceback" not in err and err.count("\n") == 1
    assert "WallReport.summarise" in err and f"dolfrag report {out}" in err
    assert "Traceback" in (out / "report_errors.txt").read_text()


def test_report_remakes_the_reports_of_a_finished_loop(failed_run, capsys):
    out, _ = failed_run
    history = (out / "history.csv").read_text()
    before = summary_of(out)
    assert cli.main(["report", str(out)]) == 0
    after = summary_of(out)
    assert after["status"] == "completed" and "report_errors" not in after
    assert after["wall"]["midspan_deflection"]["peak_m"] > 0
    assert not (out / "report_errors.txt").exists()
    # the loop was not run again: the same state, the same history
    assert (out / "history.csv").read_text() == history
    assert after["energies_J"] == before["energies_J"] and after["fragments"] == before["fragments"]
    # now complete: a --resume is refused, a report is made again
    assert cli.main(["run", "--resume", str(out)]) == 2
    assert "already complete" in capsys.readouterr().err
    assert cli.main(["report", str(out)]) == 0


def test_resume_of_a_failed_report_remakes_it_and_debug_prints_the_traceback(failed_run, monkeypatch, capsys):
    out, _ = failed_run
    monkeypatch.setattr(WallReport, "summarise", broken_summarise)
    assert cli.main(["run", "--resume", str(out), "--debug"]) == 1
    assert "Traceback" in capsys.readouterr().err
    monkeypatch.undo()
    assert cli.main(["run", "--resume", str(out)]) == 0
    assert summary_of(out)["status"] == "completed"


def test_report_refuses_a_loop_that_has_not_finished(tmp_path, monkeypatch, capsys):
    out = tmp_path / "stopped"
    monkeypatch.setenv("DOLFRAG_SIGNAL_AT_STEP", "5")
    assert cli.main([*WALL, "--out", str(out)]) == 143
    monkeypatch.delenv("DOLFRAG_SIGNAL_AT_STEP")
    capsys.readouterr()
    assert cli.main(["report", str(out)]) == 2
    assert "has not finished" in capsys.readouterr().err


def test_a_stop_while_the_figures_are_made_names_what_is_missing(tmp_path, monkeypatch, capsys):
    out = tmp_path / "late"
    figures = driver.common_figures

    def figures_then_sigterm(*args):
        os.kill(os.getpid(), signal.SIGTERM)  # arrives while the common figures are drawn
        return figures(*args)

    monkeypatch.setattr(driver, "common_figures", figures_then_sigterm)
    assert cli.main([*WALL, "--out", str(out)]) == 143
    err = capsys.readouterr().err
    summary = summary_of(out)
    assert summary["status"] == "interrupted" and summary["signal"] == "SIGTERM"
    assert summary["missing_outputs"] == ["WallReport.figures"]  # the part in progress finished
    assert (out / "figures" / "damage.png").is_file() and not (out / "figures" / "deflection.png").exists()
    assert "wall" in summary and "fragments" in summary  # made before the figures
    assert err.count("\n") == 1 and "not made: WallReport.figures" in err and f"dolfrag report {out}" in err
    monkeypatch.undo()
    assert cli.main(["report", str(out)]) == 0
    assert summary_of(out)["status"] == "completed" and (out / "figures" / "deflection.png").is_file()
