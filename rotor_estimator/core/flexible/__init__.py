# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Flexible-rotor model: FE shaft (Timoshenko), disks, bearings, pedestals, modal
reduction (Neisi et al. 2022, Eqs. 1-10 and Appendix A) and its discrete state space."""
from rotor_estimator.core.flexible.description import (Bearing, Disk, Material, ModelOptions, Pedestal,
                                                       RotorDescription, Sensor, ShaftSection, Station, Unbalance,
                                                       load_rotor_description, rotor_from_mapping)
from rotor_estimator.core.flexible.fe_rotor import FERotor, assemble, timoshenko_element
from rotor_estimator.core.flexible.modal import ReducedModel, reduce, state_matrices, whirl_modes
from rotor_estimator.core.flexible.state_space import (FlexibleStateSpace, Simulation, build_state_space,
                                                       periodic_steady_state, simulate, station_outputs,
                                                       unbalance_inputs)

__all__ = [
    "Bearing", "Disk", "Material", "ModelOptions", "Pedestal", "RotorDescription", "Sensor", "ShaftSection",
    "Station", "Unbalance", "load_rotor_description", "rotor_from_mapping", "FERotor", "assemble",
    "timoshenko_element", "ReducedModel", "reduce", "state_matrices", "whirl_modes", "FlexibleStateSpace",
    "Simulation", "build_state_space", "periodic_steady_state", "simulate", "station_outputs", "unbalance_inputs",
]
