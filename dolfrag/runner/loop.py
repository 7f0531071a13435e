"""The time loop: step the integrator, let the observers look, write a history row when
one is due, checkpoint every output.checkpoint_every seconds of wall time and at the end,
stop at the end of a step when a signal came (runner/signals.py), or within a long step
(solver/interrupt.py): then back to the state before it."""
from time import perf_counter

from dolfrag.runner.context import Step
from dolfrag.solver.interrupt import StepInterrupted

# s: a step that took this long makes the next ones abandonable midway. Open MPI's mpirun
# kills its ranks about 1 s after passing them its SIGTERM (docs/usage.md): a step shorter
# than this is left to finish. Shorter steps are not guarded, since guarding one costs a
# copy of the run's state (checkpoint.Rewind.mark).
GUARD_AFTER = 0.2


class Guard:
    """What lets a step be abandoned: the integrator's ``interrupt`` set to the stop request
    (runner/signals.Stop) and the state before the step kept in memory (rewind, a
    checkpoint.Rewind of what a step changes)."""

    def __init__(self, integ, stop, rewind):
        self.integ, self.stop, self.rewind = integ, stop, rewind

    def arm(self, on):
        """Make the next step abandonable (on) or not."""
        self.integ.interrupt = self.stop if on else None
        if on:
            self.rewind.mark()

    def restore(self):
        self.rewind.restore()


def time_loop(ctx, observers, rows, output, stop, save, progress, first_step=0, guard=None):
    """Steps first_step + 1 .. n_steps. observers: objects with ``observe(Step)``; rows:
    objects with ``values(Step)``, the history columns in order; save(k): write the
    checkpoint after step k; guard: a Guard, for an integrator that can abandon a step on a
    stop request, else None; it is armed for the first step and after a step of
    GUARD_AFTER s or more on any rank. Returns the last step completed. Collective."""
    integ, case = ctx.integ, ctx.case
    n_steps, every, interval = ctx.problem.n_steps, case.output.every, case.output.checkpoint_every
    saved_at = perf_counter()
    broken_column = [column for row in rows for column in row.columns].index("broken_links")
    broken = 0  # the last history row's, for the progress line
    slow = True  # the first step's cost is not known
    for k in range(first_step + 1, n_steps + 1):
        t_n, started = integ.t, perf_counter()
        if guard is not None:
            guard.arm(slow)
        try:
            step = Step(k, t_n, integ.step(energies=k % every == 0 or k == n_steps))
        except StepInterrupted:
            guard.restore()
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
        now = perf_counter()
        stopping, due, slow = stop.requested(k, now - saved_at >= interval, now - started >= GUARD_AFTER)
        if stopping or due or k == n_steps:
            save(k)
            saved_at = perf_counter()
        if stopping:
            return k
    return n_steps
