"""Benchmarks of msf-contact (issue 5): ``python -m benchmarks.run`` or ``make bench``.

Timing lives here, never in ``tests/``. Each module has ``run(quick) -> list[dict]``
returning records (see :mod:`benchmarks.run` for the fields).
"""
