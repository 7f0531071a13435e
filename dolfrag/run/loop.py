"""The time loop: step the integrator, let the observers look, write a history row when
one is due, checkpoint every output.checkpoint_every seconds of wall time and at the end,
stop at the end of a step when a signal came (run/signals.py)."""
import dataclasses
from time import perf_counter

from dolfrag.run.context import Step


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


def time_loop(ctx, observers, rows, output, stop, save, progress, first_step=0):
    """Steps first_step + 1 .. n_steps. observers: objects with ``observe(Step)``; rows:
    objects with ``values(Step)``, the history columns in order; save(k): write the
    checkpoint after step k. Returns the last step taken. Collective."""
    integ, case = ctx.integ, ctx.case
    n_steps, every, interval = ctx.problem.n_steps, case.output.every, case.output.checkpoint_every
    saved_at = perf_counter()
    for k in range(first_step + 1, n_steps + 1):
        t_n = integ.t
        step = Step(k, t_n, advance(ctx, k % every == 0 or k == n_steps))
        for observer in observers:
            observer.observe(step)
        if step.energies is not None:
            output.row([value for row in rows for value in row.values(step)])
        progress.update(k)
        integ.timer.lap("output")
        stopping, due = stop.requested(k, perf_counter() - saved_at >= interval)
        if stopping or due or k == n_steps:
            save(k)
            saved_at = perf_counter()
        if stopping:
            return k
    return n_steps
