"""Blind cases from ROSS (``ross-rotordynamics`` 2.3.0, optional extra): an independent FE simulator.

ROSS builds a Timoshenko finite-element rotor (6 DOF per node) with its own bearing,
disk and point-mass elements and integrates it with ``Rotor.run_time_response``
(``scipy.signal.lsim`` of its own state-space model). Nothing here reuses this package's
model, so a case generated here tests the diagnosis on dynamics it did not write:

* ``shaft_bending``: a slender shaft (d = 20-26 mm) whose bending flexibility is real
  FE flexibility, not the diagnosis's single pinned-pinned mode;
* ``pedestal``: a stiff shaft whose bearings link (``n_link``) to point masses on support
  bearings (ROSS's foundation model);
* ``none``: a stiff shaft on rigid supports (a control: the rigid model should suffice).

The rig file handed to the diagnosis is derived from the FE rotor's geometry (mass,
inertias about the mass center, stations), as a user would write it from drawings.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np

from ..config import Imbalance, RigConfig, RigFile, load_rig_file
from ..recording import RigRecording
from ..simulator import SIMULATION_EPOCH_NS, Impact

NODE_PITCH_M = 0.025
N_ELEMENTS = 16
X0_M = -0.2
BEARING_NODES = (3, 13)
PROBE_NODES = (4, 12)
IMPACT_NODE = 8
IMBALANCE_NODES = (1, 15)
DISK = {"m": 1.2, "Id": 2.0e-3, "Ip": 3.5e-3}
RHO, E, G = 7810.0, 211e9, 81.2e9


def ross_available() -> bool:
    """True when ``import ross`` works (``pip install ross-rotordynamics==2.3.0 'plotly<6'``)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import ross  # noqa: F401
    except Exception:  # ImportError, or a broken optional dependency
        return False
    return True


def _build(diameter_m: float, r: np.ndarray, pedestal: tuple[float, float, float] | None):
    import contextlib
    import io

    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        warnings.simplefilter("ignore")
        import ross as rs

        steel = rs.Material(name="steel_diag", rho=RHO, E=E, G_s=G)
        shaft = [rs.ShaftElement(L=NODE_PITCH_M, idl=0.0, odl=diameter_m, material=steel, shear_effects=True,
                                 rotary_inertia=True, gyroscopic=True) for _ in range(N_ELEMENTS)]
        disks = [rs.DiskElement(n=IMPACT_NODE, m=DISK["m"], Id=DISK["Id"], Ip=DISK["Ip"])]
        kw = dict(kxx=r[0], kxy=r[1], kyx=r[2], kyy=r[3], cxx=r[4], cxy=r[5], cyx=r[6], cyy=r[7])
        bearings, masses = [], []
        if pedestal is None:
            bearings = [rs.BearingElement(n=n, **kw) for n in BEARING_NODES]
        else:
            m_p, k_p, c_p = pedestal
            for j, n in enumerate(BEARING_NODES):
                link = N_ELEMENTS + 1 + j
                bearings.append(rs.BearingElement(n=n, n_link=link, **kw))
                bearings.append(rs.BearingElement(n=link, kxx=k_p, kyy=k_p, cxx=c_p, cyy=c_p))
                masses.append(rs.PointMass(n=link, m=m_p))
        return rs.Rotor(shaft, disks, bearings, masses)


def rig_from_geometry(diameter_m: float, speed_rad_s: float, noise_std_m: float) -> RigConfig:
    """Rigid-rotor rig file of the FE rotor: mass, inertias about the mass center, stations."""
    s_nodes = X0_M + NODE_PITCH_M * np.arange(N_ELEMENTS + 1)
    area = math.pi * diameter_m ** 2 / 4
    m_e = RHO * area * NODE_PITCH_M
    s_e = s_nodes[:-1] + NODE_PITCH_M / 2
    m_tot = m_e * N_ELEMENTS + DISK["m"]
    cg = (m_e * s_e.sum() + DISK["m"] * s_nodes[IMPACT_NODE]) / m_tot
    it = (N_ELEMENTS * m_e * (diameter_m ** 2 / 16 + NODE_PITCH_M ** 2 / 12) + m_e * np.sum((s_e - cg) ** 2)
          + DISK["Id"] + DISK["m"] * (s_nodes[IMPACT_NODE] - cg) ** 2)
    ip = N_ELEMENTS * m_e * diameter_m ** 2 / 8 + DISK["Ip"]
    pos = lambda n: float(s_nodes[n] - cg)  # noqa: E731
    base = load_rig_file().rig
    imb = tuple(Imbalance(u.mass_kg, u.radius_m, u.phase_rad, pos(n)) for u, n in zip(base.imbalances, IMBALANCE_NODES))
    return RigConfig(name=f"ross_fe_d{diameter_m * 1e3:.0f}mm", shaft_mass_kg=float(m_tot), polar_inertia_kg_m2=float(ip),
                     transverse_inertia_kg_m2=float(it), bearing1_position_m=pos(BEARING_NODES[0]),
                     bearing2_position_m=pos(BEARING_NODES[1]), probe1_position_m=pos(PROBE_NODES[0]),
                     probe2_position_m=pos(PROBE_NODES[1]), impact_position_m=pos(IMPACT_NODE), imbalances=imb,
                     speed_rad_s=speed_rad_s, sample_rate_hz=base.sample_rate_hz, noise_std_m=noise_std_m).validate()


def simulate_ross(diameter_m: float, r: np.ndarray, speed_rad_s: float, impacts: tuple[Impact, ...], duration_s: float,
                  noise_std_m: float, seed: int, pedestal=None, lead_in_s: float = 0.25, oversample: int = 2):
    """Probe record of the ROSS rotor: (recording, rig, realized noise RMS)."""
    rotor = _build(diameter_m, r, pedestal)
    rig = rig_from_geometry(diameter_m, speed_rad_s, noise_std_m)
    dt = rig.sample_period_s
    h = dt / oversample
    n_lead = int(round(lead_in_s / dt))
    n_rec = int(round(duration_s / dt))
    t = np.arange((n_lead + n_rec) * oversample + 1) * h
    nd = rotor.number_dof
    f = np.zeros((t.size, rotor.ndof))
    base = load_rig_file().rig
    for u, node in zip(base.imbalances, IMBALANCE_NODES):
        a = speed_rad_s * t + u.phase_rad
        f[:, nd * node] += u.moment_kg_m * speed_rad_s ** 2 * np.cos(a)
        f[:, nd * node + 1] += u.moment_kg_m * speed_rad_s ** 2 * np.sin(a)
    for imp in impacts:  # a rectangle [start, start + dt) on the linear-interpolation grid, impulse preserved
        k0 = int(round((lead_in_s + imp.start_s) / h))
        shape = np.zeros(t.size)
        shape[k0:k0 + oversample + 1] = 1.0
        shape[k0] = shape[k0 + oversample] = 0.5
        f[:, nd * IMPACT_NODE] += imp.force_x_n * shape
        f[:, nd * IMPACT_NODE + 1] += imp.force_y_n * shape
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = rotor.run_time_response(speed_rad_s, f, t)
    yout = np.asarray(res.yout)
    idx = np.arange(n_lead, n_lead + n_rec) * oversample
    clean = np.column_stack([yout[idx, nd * PROBE_NODES[0]], yout[idx, nd * PROBE_NODES[0] + 1],
                             yout[idx, nd * PROBE_NODES[1]], yout[idx, nd * PROBE_NODES[1] + 1]])
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal(clean.shape) * noise_std_m
    t_rec = np.arange(n_rec) * dt
    force = np.zeros((n_rec, 2))
    for imp in impacts:
        k = int(round(imp.start_s / dt))
        force[k] += (imp.force_x_n, imp.force_y_n)
    t_abs0 = lead_in_s
    kk = np.arange(math.ceil(speed_rad_s * t_abs0 / (2 * math.pi)) - 1,
                   math.floor(speed_rad_s * (t_abs0 + duration_s) / (2 * math.pi)) + 2)
    pulses = 2 * math.pi * kk / speed_rad_s - t_abs0
    rec = RigRecording(SIMULATION_EPOCH_NS + np.round(t_rec * 1e9).astype(np.int64), clean + noise,
                       SIMULATION_EPOCH_NS + np.round(pulses * 1e9).astype(np.int64), force,
                       meta={"generator": "ross"})
    return rec, rig, float(np.sqrt(np.mean(noise[int(0.01 / dt):] ** 2)))


def plan(n_cases: int, seed: int) -> list[tuple[tuple[str, ...], int, dict]]:
    """ROSS share of a blind set: a control, two flexible shafts and a pedestal (about 10 %)."""
    rng = np.random.default_rng(seed + 77)
    out = [((), seed * 1000 + 900, {"diameter_m": 0.05}),
           (("shaft_bending",), seed * 1000 + 901, {"diameter_m": float(rng.uniform(0.020, 0.024))}),
           (("pedestal",), seed * 1000 + 902, {"diameter_m": 0.05, "pedestal": "auto"})]
    if n_cases >= 36:
        out.append((("shaft_bending",), seed * 1000 + 903, {"diameter_m": float(rng.uniform(0.022, 0.026))}))
    return out


def make_case(case_id: str, names: tuple[str, ...], seed: int, *, diameter_m: float, pedestal=None):
    from .blind import BlindCase, _random_impacts

    rng = np.random.default_rng(seed)
    speed = float(rng.uniform(10000, 20000)) * math.pi / 30
    noise = float(rng.uniform(0.5e-6, 1.5e-6))
    duration = 0.25
    base = load_rig_file()
    r_true = base.rig.true_coefficients.as_array() * rng.uniform(0.8, 1.2, size=8)
    ped = None
    if pedestal == "auto":
        m_p = float(rng.uniform(2.0, 5.0))
        f_p = float(rng.uniform(120.0, 220.0))
        k_p = m_p * (2 * math.pi * f_p) ** 2
        ped = (m_p, k_p, 2 * 0.05 * math.sqrt(k_p * m_p))
    impacts = _random_impacts(rng, duration)
    rec, rig, noise_rms = simulate_ross(diameter_m, r_true, speed, impacts, duration, noise, seed, pedestal=ped)
    label = {"effects": list(names), "generator": "ross", "near_limit_target": False, "target_gap": [],
             "noise_std_m": noise, "noise_rms_m": noise_rms, "speed_rpm": speed * 30 / math.pi,
             "true_coefficients": [float(v) for v in r_true], "ross": {"diameter_m": diameter_m, "pedestal": ped}}
    return BlindCase(case_id, rec, RigFile(rig=replace(rig, true_coefficients=None), estimator=base.estimator), label)


__all__ = ["ross_available", "simulate_ross", "rig_from_geometry", "plan", "make_case"]
