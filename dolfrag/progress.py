"""A one-line progress bar on rank 0 (stderr), silent when quiet."""
import sys
import time


class Progress:
    def __init__(self, total, quiet=False, rank=0, label="steps"):
        self.total, self.label = total, label
        self.on = not quiet and rank == 0
        self.start = time.perf_counter()
        self.shown = -10
        self.tty = sys.stderr.isatty()

    def update(self, done, note=""):
        if not self.on:
            return
        percent = 100 * done // self.total
        step = 1 if self.tty else 10  # a log file gets ten lines, a terminal a live bar
        if percent // step == self.shown // step and done != self.total:
            return
        self.shown = percent
        elapsed = time.perf_counter() - self.start
        eta = elapsed * (self.total - done) / done if done else 0.0
        bar = "#" * (percent // 4)
        sys.stderr.write(("\r" if self.tty else "") + f"[{bar:<25}] {percent:3d}% {done}/{self.total} {self.label} "
                         f"{elapsed:6.1f} s, {eta:6.1f} s left {note}")
        if done == self.total or not self.tty:
            sys.stderr.write("\n")
        sys.stderr.flush()
