"""A run: the time loop (loop.py) and its observers: monitors, per-kind reports (reports/),
checkpoints and signals. ``dolfrag.run`` is driver.run."""
