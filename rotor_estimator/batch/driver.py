# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""A batch: every recording through one command on Dask, rows written to the table as they arrive.

Resumable: recordings with a status-ok row in the existing table are skipped (``force``: recomputed);
error rows are retried. The table is rewritten atomically at most every ``flush_every_s`` and when the
batch ends for any reason (an interrupt keeps every finished row).
"""
from __future__ import annotations

import datetime
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from rotor_estimator.batch.runner import run_tasks
from rotor_estimator.batch.table import ERROR, OK, finished, read_table, table_format, write_table
from rotor_estimator.batch.tasks import BatchOptions, package_version, run_row
from rotor_estimator.core.errors import InputError


@dataclass
class BatchSummary:
    """What a batch did: recordings computed and skipped, errors, the rows of the table, wall time."""

    computed: int
    skipped: int
    errors: int
    rows: list[dict] = field(repr=False)
    seconds: float


class TableWriter:
    """The rows of a table kept by recording, written atomically to ``path`` (throttled)."""

    def __init__(self, path: str | Path | None, command: str, rows: list[dict], order: list[str],
                 flush_every_s: float = 1.0) -> None:
        self.path, self.command, self.flush_every_s = path, command, flush_every_s
        self.rows = {r["recording"]: r for r in rows}
        self.order = order
        self.dirty = False
        self.last = 0.0

    def add(self, row: dict) -> None:
        self.rows[row["recording"]] = row
        self.dirty = True
        if time.monotonic() - self.last >= self.flush_every_s:
            self.flush()

    def ordered(self) -> list[dict]:
        """Rows in the order of this batch's inputs, then rows of earlier batches not among them."""
        first = [self.rows[p] for p in self.order if p in self.rows]
        seen = set(self.order)
        return first + [r for p, r in self.rows.items() if p not in seen]

    def flush(self) -> None:
        if self.path is not None and self.dirty:
            write_table(self.path, self.ordered(), self.command)
        self.dirty = False
        self.last = time.monotonic()


def _row_decimate(row: dict) -> str:
    """The ``--decimate`` a diagnose row was computed with (tables written before the column: 1, the full rate)."""
    value = row.get("decimate")
    return "1" if value is None or (isinstance(value, float) and math.isnan(value)) or value == "" else str(value)


def run_batch(options: BatchOptions, recordings: list[str], out: str | Path | None = None, *,
              workers: int | None = None, scheduler: str | None = None, force: bool = False,
              progress: bool = True, on_row: Callable[[dict], Any] | None = None,
              flush_every_s: float = 1.0) -> BatchSummary:
    """Run ``options.command`` on every path of ``recordings`` and write the table ``out`` (None: no file).

    ``on_row(row)`` is called as each row arrives (after it is recorded)."""
    options.validate()
    t0 = time.perf_counter()
    previous: list[dict] = []
    if out is not None:
        table_format(out)  # a bad extension is refused before any work
        if Path(out).exists():
            command, previous = read_table(out)
            if command is not None and command != options.command:
                raise InputError(f"--out {out}: holds {command} rows; a {options.command} batch needs its own table")
            asked = str(options.diagnose_decimate)
            others = sorted({_row_decimate(r) for r in previous if r.get("status") == OK} - {asked})
            if options.command == "diagnose" and others and not force:
                raise InputError(f"--out {out}: holds rows diagnosed with --decimate {', '.join(others)}; a "
                                 f"--decimate {asked} batch needs its own table (or --force to redo them)")
    done = set() if force else finished(previous)
    todo = [p for p in recordings if p not in done]
    writer = TableWriter(out, options.command, previous, list(recordings), flush_every_s)
    computed = errors = 0
    try:
        if todo:
            results = run_tasks(run_row, [(p, options) for p in todo], workers=workers, scheduler=scheduler,
                                progress=progress, desc=f"batch {options.command}")
            try:
                for outcome in results:
                    row = outcome.result
                    if outcome.error is not None:  # the worker died or the task could not run at all
                        path = outcome.item[0]
                        row = {"recording": path, "command": options.command, "status": ERROR,
                               "error": outcome.error, "version": package_version(),
                               "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
                    writer.add(row)
                    computed += 1
                    errors += row["status"] == ERROR
                    if on_row is not None:
                        on_row(row)
            finally:
                results.close()
        writer.dirty = writer.dirty or (out is not None and not Path(out).exists())
    finally:
        writer.flush()
    return BatchSummary(computed, len(recordings) - len(todo), errors, writer.ordered(), time.perf_counter() - t0)
