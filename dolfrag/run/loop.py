"""The time loop: step the integrator, let the observers look, write a history row when
one is due, checkpoint every output.checkpoint_every seconds of wall time and at the end,
stop at the end of a step when a signal came (run/signals.py), or within it for an
integrator that can abandon a step (theta): then back to the state before it."""
import dataclasses
from time import perf_counter

from dolfrag.run.context import Step
from dolfrag.solver.theta import StepInterrupted


def advance(ctx, energies):
    """One step of the integrator; the Energies at its mid-step if ``energies``, else None.
    A stretch books its ends' work, and adds it with E_{-1/2} to the external work."""
    integ, stretch = ctx.integ, ctx.stretch
    result = integ.step(energies=energies)
    if stretch is not None:
        stretch.book(integ)
        if result is not None:
            result = dataclasses.replace(result, external_work=result.external_work + stretch.supplied(ctx.comm))
    return result


def time_loop(ctx, observers, rows, output, stop, save, progress, first_step=0, rewind=None):
    """Steps first_step + 1 .. n_steps. observers: objects with ``observe(Step)``; rows:
    objects with ``values(Step)``, the history columns in order; save(k): write the
    checkpoint after step k; rewind: a checkpoint.Rewind of what a step changes, for an
    integrator that abandons a step on a stop request (its ``interrupt``), else None.
    Returns the last step completed. Collective."""
    integ, case = ctx.integ, ctx.case
    n_steps, every, interval = ctx.problem.n_steps, case.output.every, case.output.checkpoint_every
    saved_at = perf_counter()
    broken_column = [column for row in rows for column in row.columns].index("broken_links")
    broken = 0  # the last history row's, for the progress line
    for k in range(first_step + 1, n_steps + 1):
        t_n = integ.t
        if rewind is not None:
            rewind.mark()
        try:
            step = Step(k, t_n, advance(ctx, k % every == 0 or k == n_steps))
        except StepInterrupted:
            rewind.restore()
            save(k - 1)
            return k - 1
        for observer in observers:
            observer.observe(step)
        if step.energies is not None:
            values = [value for row in rows for value in row.values(step)]
            output.row(values)
            broken = values[broken_column]
        progress.update(k, integ.t, broken)
        integ.timer.lap("output")
        stopping, due = stop.requested(k, perf_counter() - saved_at >= interval)
        if stopping or due or k == n_steps:
            save(k)
            saved_at = perf_counter()
        if stopping:
            return k
    return n_steps
