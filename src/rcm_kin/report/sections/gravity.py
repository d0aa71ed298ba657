"""Holding-effort maps with the thesis's Fig 4.6/4.7 curves, the drive parameters, and the
counterweights of the osMDV masses designed on the CAD model."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.model import load_robot
from rcm_kin.report.render import Table, relative
from rcm_kin.thesis import FIGURES, OSMDV_COUNTERWEIGHTS, SOURCES


@dataclass(frozen=True)
class GravitySection:
    template: ClassVar[str] = "gravity.html.j2"
    insertion_mm: float                 # of the roll x pitch map
    map_points: int                     # per axis
    figures: dict[str, str]             # torque_map, trend_curves, insertion_map -> PNG
    data: dict[str, str]                # CSV name -> path
    drive: Table
    drive_source: str                   # file name of the drive parameters
    gravity_offsets: str                # calibrated first moments, as text
    designs: Table
    design_points: int
    design_range_deg: tuple[float, float, float, float]   # roll lo, hi, pitch lo, hi
    osmdv_main: tuple[float, float]     # kg, mm below the roll axis (as built)
    osmdv_dpm: tuple[float, float, float]   # kg, mm from the pitch pivot, deg
    osmdv_source: str
    dpm_distance_ratio: float           # DPM distance for roll and pitch over the osMDV one
    thesis_figures: dict[str, str]


def _design_row(name: str, d) -> list[str]:
    return [name, f"{d.main_mass:.2f} kg at {d.main_distance * 1e3:.1f} mm",
            f"{d.dpm_mass:.2f} kg at {d.dpm_distance * 1e3:.1f} mm, {np.degrees(d.dpm_angle):.2f} deg",
            f"{d.rms_pwm[0]:.2f} / {d.peak_pwm[0]:.2f}", f"{d.rms_pwm[1]:.2f} / {d.peak_pwm[1]:.2f}"]


def gravity_section(out: Path, map_points: int = 61, design_points: int = 13) -> GravitySection:
    """The maps (``map_points`` per axis over the roll and pitch ranges, at the home insertion)
    and the counterweight designs (``design_points`` per axis), written into ``out``."""
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.statics.counterweights import osmdv_designs
    from rcm_kin.statics.maps import write_gravity_maps

    psm = load_robot("psm")
    drive = load_drive_parameters()
    roll, pitch = (np.linspace(*np.degrees([psm.lower[k], psm.upper[k]]), map_points) for k in (0, 1))
    _, files = write_gravity_maps(psm, drive, roll, pitch, HOME_INSERTION, out)
    paths = {f.name: relative(f, out) for f in files}
    designs = osmdv_designs(drive, design_points)
    main, dpm = OSMDV_COUNTERWEIGHTS["main"], OSMDV_COUNTERWEIGHTS["dpm"]
    drive_rows = [[j, f"{d.gear_ratio:.4g}", f"{d.volts_per_pwm:.4g}", f"{d.pwm_per_torque:+.3f}",
                   f"{d.pwm_limit:g}", f"{d.coulomb:.3g}"] for j, d in drive.joints.items()]
    return GravitySection(
        insertion_mm=HOME_INSERTION * 1e3, map_points=map_points,
        figures={k: paths[f"{k}.png"] for k in ("torque_map", "trend_curves", "insertion_map")},
        data={name: path for name, path in paths.items() if name.endswith(".csv")},
        drive=Table.of(drive_rows, ["joint", "gear ratio", "V per PWM", "PWM per N m (N)", "PWM limit",
                                    "Coulomb (N m, N)"]),
        drive_source=Path(drive.source).name,
        gravity_offsets=", ".join(f"{k} {np.round(v, 4).tolist()}" for k, v in drive.gravity_offsets.items()),
        designs=Table.of([_design_row("roll only, DPM as osMDV built it", designs.roll_only),
                          _design_row("roll and pitch, both designed", designs.roll_and_pitch)],
                         ["design", "main counterweight", "DPM counterweight", "roll RMS / peak PWM",
                          "pitch RMS / peak PWM"]),
        design_points=designs.points, design_range_deg=designs.roll_range_deg + designs.pitch_range_deg,
        osmdv_main=(main[0], main[1] * 1e3), osmdv_dpm=(dpm[0], dpm[1] * 1e3, float(np.degrees(dpm[2]))),
        osmdv_source=SOURCES["OSMDV_COUNTERWEIGHTS"],
        dpm_distance_ratio=designs.roll_and_pitch.dpm_distance / dpm[1],
        thesis_figures=FIGURES)
