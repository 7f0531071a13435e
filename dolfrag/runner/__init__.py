"""A run: the time loop (loop.py) and its observers: monitors, per-kind reports (reports/),
checkpoints and signals. The entry point ``dolfrag.run`` is driver.run; this package is
``dolfrag.runner``, so that the two names do not clash."""
