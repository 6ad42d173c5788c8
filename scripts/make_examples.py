"""Regenerate the example recordings shipped in ``src/robovib/datasets/examples/``.

Every file comes from the virtual robot (:mod:`robovib.sim`) with a fixed seed, small enough to
ship (< ~300 KB each)::

    python scripts/make_examples.py            # rewrite the examples
    python scripts/make_examples.py --check    # fail if a regenerated file differs in size > 5 %

Files: ``hammer.uff`` and ``hammer.csv`` (impact-hammer recordings, X direction, two poses),
``frf.csv`` (compliance FRF of ``hammer.uff`` in um/N), ``milling_record.csv`` (a 100 mm
acetal cut along the chapter-4 path: forces, tool displacement, path coordinate),
``cuts.csv`` (test cuts labelled stable/chatter by the virtual robot's true lobes at a pose),
``campaign_poses.csv`` (36 poses of the README's own-robot campaign, a mode-switch region
included), ``campaign.csv`` (a campaign manifest naming the two hammer recordings), ``poses.csv`` (30
poses for a virtual campaign and as next-pose candidates).
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "src" / "robovib" / "datasets" / "examples"
POSES_MM_DEG = {"hammer.uff": (2400.0, 0.0, 45.0), "hammer.csv": (2100.0, 300.0, 90.0)}
CUTS_POSE_MM_DEG = (2400.0, 0.0, 45.0)


def make(out: Path) -> None:
    from robovib.frf import impact_frf
    from robovib.io import write_frf_csv, write_recording
    from robovib.milling import ACETAL, ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.stability import stability_lobes
    from robovib.sim import LinearMove, VirtualRobot, simulate_hammer_test, simulate_milling

    robot = VirtualRobot()
    recs = {}
    for seed, (name, (x, y, rz)) in enumerate(POSES_MM_DEG.items()):
        rec = simulate_hammer_test(robot, (x / 1e3, y / 1e3, rz), "x", domain="workspace",
                                   n_hits=3, sample_rate_hz=512.0, duration_s=4.0, snr_db=50.0,
                                   rng=seed)  # fmt: skip
        write_recording(out / name, rec)
        recs[name] = rec
    rec = recs["hammer.uff"]
    res = impact_frf(rec.forces, rec.responses, rec.sample_rate_hz,
                     response_quantity=rec.response_quantity, f_max_hz=60.0, direction="x")  # fmt: skip
    write_frf_csv(out / "frf.csv", res.frf.to_compliance(5.0), unit="um_per_n")

    cond = CuttingConditions(2700.0, 0.3e-3, 6e-3, 6e-3)
    run = simulate_milling(robot, LinearMove("path", (0.635,), (0.735,)), MillingTool(), cond,
                           ACETAL, background_noise_rel=1.0, rng=0)  # fmt: skip
    run.to_csv(out / "milling_record.csv")

    x, y, rz = CUTS_POSE_MM_DEG
    modes = {d: robot.workspace.modes(np.array([[x / 1e3, y / 1e3, rz]]), d).at(0)
             for d in ("x", "y")}  # fmt: skip
    lobes = stability_lobes(modes["x"], modes["y"], MillingTool(),
                            CuttingConditions(1000.0, 1e-4, 1e-3, 6e-3), ALUMINIUM_7075,
                            n_lobes=40)  # fmt: skip
    rng = np.random.default_rng(0)
    rpm = rng.uniform(500.0, 3000.0, 12).round(-1)
    crit_mm = 1e3 * lobes.critical_depth(rpm)
    depth_mm = np.round(1e3 * lobes.minimum_depth_m * rng.uniform(0.5, 4.0, rpm.size), 2)
    lines = ["spindle_rpm,depth_mm,result"]
    lines += [f"{s:.0f},{d:.2f},{'chatter' if d > c else 'stable'}"
              for s, d, c in zip(rpm, depth_mm, crit_mm, strict=True)]  # fmt: skip
    (out / "cuts.csv").write_text(
        f"# test cuts at X={x:g} mm, Y={y:g} mm, Rz={rz:g} deg, ae 6 mm, al7075 "
        "(labelled by the virtual robot's true lobes)\n" + "\n".join(lines) + "\n"
    )
    rows = ["file,direction,x_mm,y_mm,z_mm,rz_deg,replicate"]
    rows += [
        f"{name},x,{px:g},{py:g},325,{prz:g},0" for name, (px, py, prz) in POSES_MM_DEG.items()
    ]
    (out / "campaign.csv").write_text("\n".join(rows) + "\n")
    # 30 poses inside the Table A1 box (X stratified) for a virtual campaign / candidates.
    gen = np.random.default_rng(7)
    n = 30
    px = 2100 + 450 * (np.arange(n) + gen.uniform(size=n)) / n
    poses = np.column_stack([px, gen.uniform(-300, 600, n), gen.uniform(0, 180, n)])
    lines = ["x_mm,y_mm,rz_deg"] + [f"{a:.1f},{b:.1f},{c:.1f}" for a, b, c in poses]
    (out / "poses.csv").write_text("\n".join(lines) + "\n")
    # The README's own-robot campaign: 33 Latin-hypercube poses over the whole Table A1 box
    # (Rz 60-120 deg beyond X 2580 mm, away from the mode switch) and 3 at full extension with
    # Rz near 0/180 deg, where the virtual robot's ~63 Hz X mode dominates.
    from scipy.stats import qmc

    s = qmc.LatinHypercube(d=3, seed=36).random(33)
    cp = np.column_stack([2100 + 600 * s[:, 0], -300 + 900 * s[:, 1], 180 * s[:, 2]])
    far = cp[:, 0] > 2580
    cp[far, 2] = 60 + 60 * s[far, 2]
    cp = np.vstack([cp, [[2690.0, 50.0, 4.0], [2700.0, 420.0, 177.0], [2685.0, -180.0, 2.0]]])
    lines = ["x_mm,y_mm,rz_deg"] + [f"{a:.1f},{b:.1f},{c:.1f}" for a, b, c in np.round(cp, 1)]
    (out / "campaign_poses.csv").write_text("\n".join(lines) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare with the shipped files")
    args = ap.parse_args(argv)
    if not args.check:
        OUT.mkdir(parents=True, exist_ok=True)
        make(OUT)
        for p in sorted(OUT.iterdir()):
            print(f"{p.name}: {p.stat().st_size / 1e3:.0f} KB")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        make(Path(tmp))
        bad = []
        for p in sorted(Path(tmp).iterdir()):
            shipped = OUT / p.name
            if not shipped.exists() or abs(shipped.stat().st_size / p.stat().st_size - 1) > 0.05:
                bad.append(p.name)
        if bad:
            print(f"examples out of date: {bad} (run scripts/make_examples.py)", file=sys.stderr)
            return 1
    shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
