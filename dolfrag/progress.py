"""A one-line progress bar of a run on rank 0 (stderr), silent when quiet: steps, simulated
time and broken links, wall time so far and left."""
import sys
import time


def clock(seconds):
    """A duration as people read it: '45 s', '3 min 20 s', '2 h 05 min'."""
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"


class Progress:
    """The time left is the rate of the steps since the first update times the steps to go:
    the first step of a run (or of a resumed one) carries one-time costs (compiled kernels
    loaded, the first factorisation) that would inflate it tenfold and more."""

    def __init__(self, total, quiet=False, rank=0):
        self.total = total
        self.on = not quiet and rank == 0
        self.start = time.perf_counter()
        self.first = None  # (steps done, time) at the first update
        self.shown = -10
        self.tty = sys.stderr.isatty()

    def update(self, done, t, broken):
        """After step ``done``, at time t (s), with ``broken`` links broken (the last history
        row's); the line is formatted only when it is drawn (at most 100 times a run)."""
        if not self.on:
            return
        now = time.perf_counter()
        if self.first is None:
            self.first = (done, now)
        percent = 100 * done // self.total
        step = 1 if self.tty else 10  # a log file gets ten lines, a terminal a live bar
        if percent // step == self.shown // step and done != self.total:
            return
        self.shown = percent
        done_0, time_0 = self.first
        left = clock((now - time_0) * (self.total - done) / (done - done_0)) + " left" if done > done_0 \
            else "estimating"
        bar = "#" * (percent // 4)
        sys.stderr.write(("\r" if self.tty else "") + f"[{bar:<25}] {percent:3d}% {done}/{self.total} steps, "
                         f"t = {t:.4g} s, {broken:,} links broken; {clock(now - self.start)}, {left}   ")
        if done == self.total or not self.tty:
            sys.stderr.write("\n")
        sys.stderr.flush()
