"""Benchmarks behind ``rotor-estimator bench ...``: scripts that print figures, never timed tests."""
