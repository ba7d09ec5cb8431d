"""Soak: replaying a long record keeps memory flat (streaming: nothing grows with the record)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from rotor_estimator.bagio import write_input_bag
from rotor_estimator.config import load_rig_file
from rotor_estimator.simulator import Scenario, paper_scenario, simulate


def _replay_peak_rss_mb(bag) -> float:
    code = ("import resource, sys\n"
            "from rotor_estimator.cli import main\n"
            f"rc = main(['replay', {str(bag)!r}, '--no-progress'])\n"
            # VmHWM: this process's own peak; ru_maxrss would carry the forking pytest worker's over exec
            "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM:')][0].split()[1]\n"
            "print('PEAK_RSS_KB', hwm, file=sys.stderr)\n"
            "sys.exit(rc)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1200,
                          env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert done.returncode == 0, done.stderr[-2000:]
    assert "samples:" in done.stdout
    return int(done.stderr.split("PEAK_RSS_KB")[1].split()[0]) / 1024.0


@pytest.mark.slow
def test_replay_rss_of_a_60_s_record_equals_that_of_a_1_s_record(tmp_path):
    """Peak RSS of `replay` over 60 s of 20 kHz data (1.2 M samples per plane, 2 passes) is within 30 MB
    of the peak over 1 s (measured: 218 MB and 220 MB)."""
    rig = load_rig_file().rig
    base = paper_scenario("imbalance+impact")
    peaks = {}
    for seconds in (1.0, 60.0):
        rec = simulate(rig, Scenario(duration_s=seconds, discard_initial_s=base.discard_initial_s,
                                     impacts=base.impacts), seed=9).recording
        bag = write_input_bag(tmp_path / f"r{seconds:g}", rec)
        del rec
        peaks[seconds] = _replay_peak_rss_mb(bag)
    assert peaks[60.0] - peaks[1.0] < 30.0, peaks
