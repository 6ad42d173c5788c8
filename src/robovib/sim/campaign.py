"""A complete virtual hammer campaign: recordings in mixed layouts, a manifest and the truth.

For every pose and direction one recording is simulated on the virtual robot
(:func:`robovib.sim.simulate_hammer_test`) and written in one of four layouts, in turn, as
measurement tools write them (never with robovib's own recording writer):

* ``"uff-pairs"`` — per hit a force and a response record (UFF 58), all load-case id 0;
* ``"uff-continuous"`` — one force and one response record holding all hits, ``duration_s``
  apart (a free-running DAQ);
* ``"uff-triaxial"`` — per hit one force and X, Y, Z response records (the cross channels
  carry a 5 % coupling of the other directions' modes);
* ``"csv-daq"`` — one continuous CSV with the time printed with 6 decimals.

The manifest ``campaign.csv`` lists them (paths relative to it); ``truth.csv`` holds the
virtual robot's dominant mode per direction at ``n_truth`` unseen poses drawn uniformly in
the bounding box of the campaign poses.

These files belong to :func:`simulate_campaign`: a rerun into the same folder removes the
recordings of the earlier run it does not write again, and refuses, before writing anything, to
write onto the poses file it reads (:mod:`robovib.files.safe_write`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..files.safe_write import atomic_output, check_output_path, remove_stale_outputs
from ..io.uff58 import Record58, write_uff58
from .dynamics import modal_response
from .experiments import _rng, simulate_hammer_test
from .truth import DIRECTIONS, VirtualRobot

__all__ = ["LAYOUTS", "SimulatedCampaign", "simulate_campaign", "truth_table"]

LAYOUTS = ("uff-pairs", "uff-continuous", "uff-triaxial", "csv-daq")
_Z_MM = 325.0
_CODE = {"x": 1, "y": 2, "z": 3}
_CROSS_COUPLING = 0.05
#: The files :func:`simulate_campaign` owns in its folder (glob patterns).
_OWNED = ("campaign.csv", "truth.csv", "recordings/pose*_[xyz].uff", "recordings/pose*_[xyz].csv")


@dataclass(frozen=True)
class SimulatedCampaign:
    """Paths of a simulated campaign.

    Attributes
    ----------
    manifest
        The campaign manifest CSV.
    truth
        ``truth.csv``: the dominant modes at unseen poses.
    recordings
        The recording files written.
    """

    manifest: Path
    truth: Path
    recordings: tuple[Path, ...]


def _poses_array(poses) -> np.ndarray:
    if isinstance(poses, str | Path):
        from ..io import read_pose_table

        poses = read_pose_table(poses, ("x_mm", "y_mm", "rz_deg"))
    if hasattr(poses, "columns"):
        missing = [c for c in ("x_mm", "y_mm", "rz_deg") if c not in poses.columns]
        if missing:
            raise ValueError(f"poses lack column(s) {', '.join(missing)}")
        poses = poses[["x_mm", "y_mm", "rz_deg"]].to_numpy(float)
    p = np.atleast_2d(np.asarray(poses, float))
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"poses must be (n, 3) = (x_mm, y_mm, rz_deg), got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("poses contain NaN or inf")
    return p


def truth_table(robot: VirtualRobot, poses) -> object:
    """The dominant mode per direction at ``poses`` (n, 3) = (x_mm, y_mm, rz_deg), a DataFrame.

    Columns: ``x_mm, y_mm, z_mm, rz_deg`` and per direction ``<d>_fn_hz``,
    ``<d>_stiffness_n_per_m``, ``<d>_damping_ns_per_m``, ``<d>_damping_ratio``.

    Parameters
    ----------
    robot : VirtualRobot
        The virtual robot.
    poses : array_like
        (n, 3) poses ``x_mm, y_mm, rz_deg``.

    Returns
    -------
    pandas.DataFrame
        One row per pose.
    """
    import pandas as pd

    p = _poses_array(poses)
    coords = np.column_stack([p[:, 0] / 1e3, p[:, 1] / 1e3, p[:, 2]])
    cols = {"x_mm": p[:, 0], "y_mm": p[:, 1], "z_mm": np.full(len(p), _Z_MM), "rz_deg": p[:, 2]}
    for d in DIRECTIONS:
        m = robot.workspace.modes(coords, d).dominant()
        cols[f"{d}_fn_hz"] = m.fn_hz[:, 0]
        cols[f"{d}_stiffness_n_per_m"] = m.stiffness_n_per_m[:, 0]
        cols[f"{d}_damping_ns_per_m"] = m.damping_ns_per_m()[:, 0]
        cols[f"{d}_damping_ratio"] = m.damping_ratio[:, 0]
    return pd.DataFrame(cols)


def _time_record(data, fs, spec, label, rsp_dir, ref_dir, hit):
    return Record58(
        data=np.asarray(data, float), x0=0.0, dx=1.0 / fs, func_type=1, ordinate_spec=spec,
        ordinate_label=label, abscissa_spec=17, abscissa_label="s", load_case_id=0,
        rsp_node=1, rsp_dir=rsp_dir, ref_node=1, ref_dir=ref_dir,
        ids=("virtual hammer", f"hit {hit}", "NONE", "NONE", "NONE"),
    )  # fmt: skip


def _cross_response(robot, coords, direction, force, fs, gen):
    modes = robot.workspace.modes(coords, direction)
    n = force.size
    params = [
        np.repeat(a.T, n, axis=1)
        for a in (modes.fn_hz, modes.stiffness_n_per_m, modes.damping_ratio)
    ]
    _, _, acc = modal_response(*params, force, 1.0 / fs)
    acc = _CROSS_COUPLING * acc
    return acc + gen.normal(size=n) * 0.01 * np.sqrt(np.mean(acc**2))


def simulate_campaign(
    poses,
    out_dir: str | Path,
    rng=None,
    *,
    directions=DIRECTIONS,
    layouts=LAYOUTS,
    n_hits: int = 3,
    duration_s: float = 2.0,
    sample_rate_hz: float = 1280.0,
    snr_db: float = 40.0,
    n_truth: int = 20,
    robot: VirtualRobot | None = None,
    scatter: tuple[float, float, float] | None = None,
) -> SimulatedCampaign:
    """Simulate a hammer campaign at ``poses`` and write recordings, manifest and truth.

    Parameters
    ----------
    poses
        (n, 3) array, DataFrame or CSV path with ``x_mm, y_mm, rz_deg`` inside the virtual
        robot's workspace (Z = 325 mm, tool axis vertical).
    out_dir
        Folder to create/fill: ``campaign.csv``, ``truth.csv``, ``recordings/``.
    rng
        Seed or :class:`numpy.random.Generator`.
    directions
        Hammer directions per pose.
    layouts
        Layouts used in turn (see the module docstring).
    n_hits, duration_s, sample_rate_hz, snr_db
        Per recording: hits, seconds per hit, sample rate [Hz], response SNR [dB].
    n_truth
        Unseen poses at which ``truth.csv`` gives the dominant modes.
    robot
        The virtual robot (default :class:`VirtualRobot`).
    scatter
        Test-to-test scatter of (fn, k, ζ), relative stds per recording
        (:func:`~robovib.sim.simulate_hammer_test`); ``None``: none.

    Returns
    -------
    SimulatedCampaign

    Raises
    ------
    ValueError
        Poses outside the workspace, unknown layouts or directions, bad counts.

    Examples
    --------
    >>> import tempfile
    >>> from robovib.sim import simulate_campaign
    >>> sim = simulate_campaign([[2400, 0, 45]], tempfile.mkdtemp(), rng=0, n_hits=1,
    ...                         duration_s=1.0, directions=("x",), n_truth=2)
    >>> sim.manifest.name, len(sim.recordings)
    ('campaign.csv', 1)
    """
    import pandas as pd

    p = _poses_array(poses)
    bad = [lay for lay in layouts if lay not in LAYOUTS]
    if bad or not layouts:
        raise ValueError(f"unknown layout(s) {bad}; expected some of {LAYOUTS}")
    if any(d not in DIRECTIONS for d in directions) or not directions:
        raise ValueError(f"directions must be some of {DIRECTIONS}, got {directions}")
    if int(n_hits) < 1 or int(n_truth) < 0:
        raise ValueError(f"need n_hits >= 1 and n_truth >= 0, got {n_hits} and {n_truth}")
    robot = robot or VirtualRobot()
    gen = _rng(rng)
    out = Path(out_dir)
    rec_dir = out / "recordings"
    inputs = [poses] if isinstance(poses, str | Path) else []
    for folder in (out, rec_dir):
        if folder.exists() and not folder.is_dir():
            raise ValueError(f"output folder {folder} exists and is not a folder")
    if out.is_dir():  # nothing written onto the poses file (or a link, FIFO...): checked first
        planned = [out / "campaign.csv", out / "truth.csv"]
        for k, (i, d) in enumerate((i, d) for i in range(len(p)) for d in directions):
            ext = "csv" if layouts[k % len(layouts)] == "csv-daq" else "uff"  # as written below
            planned.append(rec_dir / f"pose{i:03d}_{d}.{ext}")
        for target in planned if rec_dir.is_dir() else planned[:2]:
            check_output_path(target, inputs=inputs)
    rec_dir.mkdir(parents=True, exist_ok=True)
    fs = float(sample_rate_hz)
    rows, paths = [], []
    k = 0
    for i, (x_mm, y_mm, rz) in enumerate(p):
        coords = (x_mm / 1e3, y_mm / 1e3, rz)
        for d in directions:
            layout = layouts[k % len(layouts)]
            k += 1
            rec = simulate_hammer_test(
                robot, coords, d, n_hits=n_hits, sample_rate_hz=fs, duration_s=duration_s,
                snr_db=snr_db, rng=gen, scatter=scatter,
            )  # fmt: skip
            name = f"pose{i:03d}_{d}"
            code = _CODE[d]
            if layout == "uff-pairs":
                path = rec_dir / f"{name}.uff"
                recs = []
                for h in range(n_hits):
                    recs += [_time_record(rec.forces[h], fs, 13, "N", code, code, h),
                             _time_record(rec.responses[h], fs, 12, "m/s^2", code, code, h)]  # fmt: skip
                write_uff58(path, recs, inputs=inputs)
            elif layout == "uff-continuous":
                path = rec_dir / f"{name}.uff"
                write_uff58(path, [_time_record(rec.forces.ravel(), fs, 13, "N", code, code, 0),
                                   _time_record(rec.responses.ravel(), fs, 12, "m/s^2", code, code, 0)],
                            inputs=inputs)  # fmt: skip
            elif layout == "uff-triaxial":
                path = rec_dir / f"{name}.uff"
                recs = []
                for h in range(n_hits):
                    recs.append(_time_record(rec.forces[h], fs, 13, "N", code, code, h))
                    for d2 in DIRECTIONS:
                        resp = (
                            rec.responses[h]
                            if d2 == d
                            else _cross_response(robot, coords, d2, rec.forces[h], fs, gen)
                        )
                        recs.append(_time_record(resp, fs, 12, "m/s^2", _CODE[d2], code, h))
                write_uff58(path, recs, inputs=inputs)
            else:  # csv-daq: acceleration in g, 6-decimal time
                path = rec_dir / f"{name}.csv"
                f_all, a_all = rec.forces.ravel(), rec.responses.ravel() / 9.80665
                t = np.arange(f_all.size) / fs
                body = "\n".join(
                    f"{ti:.6f},{fi:.6g},{ai:.6g}"
                    for ti, fi, ai in zip(t, f_all, a_all, strict=True)
                )
                with atomic_output(path, inputs=inputs) as tmp:
                    tmp.write_text(f"time_s,force_n,acceleration_{d}_g\n{body}\n")
            paths.append(path)
            rows.append({
                "file": str(path.relative_to(out)), "direction": d, "x_mm": x_mm, "y_mm": y_mm,
                "z_mm": _Z_MM, "rz_deg": rz, "replicate": 0,
            })  # fmt: skip
    manifest = out / "campaign.csv"
    with atomic_output(manifest, inputs=inputs) as tmp:
        pd.DataFrame(rows).to_csv(tmp, index=False, float_format="%.6g")
    lo, hi = p.min(axis=0), p.max(axis=0)
    unseen = lo + (hi - lo) * gen.uniform(size=(int(n_truth), 3))
    truth = out / "truth.csv"
    with atomic_output(truth, inputs=inputs) as tmp:
        truth_table(robot, unseen).to_csv(tmp, index=False, float_format="%.9g")
    remove_stale_outputs(out, _OWNED, [manifest, truth, *paths])  # an earlier run's recordings
    return SimulatedCampaign(manifest, truth, tuple(paths))
