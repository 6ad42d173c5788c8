"""Issue 28: the lab-file cases, tried as a new user would (CLI), each with its verdict.

Run: ``PYTHONPATH=src python benchmarks/study_lab_files.py`` (about 10 s). Every recording is
a known mode (16 Hz, 2 MN/m, 5 %) hit by half-sine pulses, written by hand (never by robovib's
writers). A case passes when it ends in one clear error, or exits 0 with an FRF within 1 % of
the same data written cleanly.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import signal
from typer.testing import CliRunner

from robovib.cli import app
from robovib.frf import PlausibleRanges
from robovib.io import read_frfs

FS, MODE = 1024.0, (16.0, 2e6, 0.05)


def respond(force, fs=FS):
    fn, k, z = MODE
    wn = 2 * np.pi * fn
    m = k / wn**2
    bd, ad, _ = signal.cont2discrete(([1.0, 0, 0], [m, 2 * z * m * wn, k]), 1 / fs, method="foh")
    return signal.lfilter(np.ravel(bd), ad, force)


def pulse(n, fs, t0, width, peak):
    t = np.arange(n) / fs
    return peak * np.where((t >= t0) & (t <= t0 + width), np.sin(np.pi * (t - t0) / width), 0.0)


def hits(n_hits, n, fs=FS, seed=0, width_s=4e-3):
    rng = np.random.default_rng(seed)
    f = [
        pulse(n, fs, 0.03 + rng.uniform(0, 0.01), width_s, rng.uniform(300, 700))
        for _ in range(n_hits)
    ]
    r = [respond(x, fs) for x in f]
    return f, [x + rng.normal(size=n) * 0.01 * np.std(x) for x in r]


def write(path, forces, resp, fs=FS, *, sep=",", comma=False, bom=False, head=None):
    head = head or ["hit", "time_s", "force_n", "acceleration_m_per_s2"]

    def c(v):
        s = f"{v:.10g}"
        return s.replace(".", ",") if comma else s

    lines = [sep.join(head)]
    for h, (f, r) in enumerate(zip(forces, resp, strict=True)):
        lines += [sep.join([str(h), c(i / fs), c(f[i]), c(r[i])]) for i in range(len(f))]
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + ("\n".join(lines) + "\n").encode())


def cli(*args):
    r = CliRunner().invoke(app, [str(a) for a in args])
    err = [ln for ln in r.output.splitlines() if ln.lower().startswith("error:")]
    if err:
        return r.exit_code, " ".join(r.output[r.output.lower().index("error:") :].split())
    skipped = [ln for ln in r.output.splitlines() if ln.startswith("skipped")]
    return r.exit_code, " ".join(" ".join(skipped + r.output.splitlines()[-2:]).split())


def short(msg: str, n: int = 150) -> str:
    """The error's start and, when it names one, its likely unit mix-up."""
    if "likely" not in msg[n:]:
        return msg[:n]
    return f"{msg[:80]} ... {msg[msg.index('likely') :][: n - 80]}"


def frf_case(tmp, name, clean, messy, *extra):
    outs = []
    for tag, p in (("clean", clean), ("case", messy)):
        code, msg = cli(
            "frf", "compute", p, "-o", tmp / f"{name}-{tag}.h5", "--fmin", "5", "--fmax", "60",
            *extra,
        )  # fmt: skip
        if code:
            return f"clear error: {short(msg)}" if tag == "case" else f"CLEAN FAILED {msg}"
        outs.append(read_frfs(tmp / f"{name}-{tag}.h5")[0])
    a, b = outs
    if a.frequency_hz.shape != b.frequency_hz.shape:
        return f"WORSE: df {b.df_hz:.3g} Hz vs clean {a.df_hz:.3g} Hz"
    d = float(np.max(np.abs(b.values - a.values) / np.abs(a.values)))
    return f"{'correct result' if d < 0.01 else 'WORSE'}: max |H - H_clean| / |H_clean| = {d:.2g}, df = {b.df_hz:.3g} Hz"


def main() -> int:
    tmp = Path(tempfile.mkdtemp())
    rows = []
    n = 2048
    f, r = hits(4, n)
    write(tmp / "clean3.csv", f[:3], r[:3])
    write(tmp / "short.csv", [*f[:3], f[3][:100]], [*r[:3], r[3][:100]])
    rows.append(
        (
            "short last hit (100 of 2048 samples)",
            frf_case(tmp, "short", tmp / "clean3.csv", tmp / "short.csv"),
        )
    )
    two = [np.minimum(x, np.sort(x)[-2]) for x in f[:3]]
    write(tmp / "clip2.csv", two, r[:3])
    rows.append(
        (
            "force clipped to 2 equal samples (1 kHz-class hit)",
            frf_case(tmp, "clip2", tmp / "clean3.csv", tmp / "clip2.csv"),
        )
    )
    fsh = 51200.0
    fh, rh = hits(3, 65536, fsh, 1, width_s=1e-3)  # 1 ms pulses: ~5 samples within 1 % free
    noisy = []
    for x in fh:
        lim = np.sort(x)[-36]
        y = np.minimum(x, lim)
        noisy.append(y + (y >= lim) * np.random.default_rng(2).normal(size=y.size) * 0.002 * lim)
    write(tmp / "cleanh.csv", fh, rh, fsh)
    write(tmp / "clipnoisy.csv", noisy, rh, fsh)
    rows.append(
        (
            "force clipped, 36 noisy samples within 1 % of max",
            frf_case(tmp, "clipn", tmp / "cleanh.csv", tmp / "clipnoisy.csv"),
        )
    )
    write(tmp / "kn.csv", [x / 1e3 for x in f[:3]], r[:3])
    rows.append(("force in kN labelled N", frf_case(tmp, "kn", tmp / "clean3.csv", tmp / "kn.csv")))
    write(tmp / "gq.csv", f[:3], [x * 1e-3 / 9.80665 for x in r[:3]])
    write(tmp / "cleanq.csv", f[:3], [x * 1e-3 for x in r[:3]])
    rows.append(
        (  # a 1000x quieter response at the same force is a 1000x stiffer structure: the FRF
            # range is widened so that the response level check alone is tried
            "quiet response in g labelled m/s^2 (--compliance-range 1e-10 1e-3)",
            frf_case(
                tmp, "gq", tmp / "cleanq.csv", tmp / "gq.csv", "--compliance-range", "1e-10", "1e-3"
            ),
        )
    )
    write(tmp / "g.csv", f[:3], [x / 9.80665 for x in r[:3]])
    rows.append(
        (
            "normal response in g labelled m/s^2",
            frf_case(tmp, "g", tmp / "clean3.csv", tmp / "g.csv"),
        )
    )
    write(tmp / "bom.csv", f[:3], r[:3], bom=True)
    rows.append(
        ("recording CSV with a BOM", frf_case(tmp, "bom", tmp / "clean3.csv", tmp / "bom.csv"))
    )
    write(tmp / "semi.csv", f[:3], r[:3], sep=";", comma=True)
    rows.append(
        ("';' and decimal comma", frf_case(tmp, "semi", tmp / "clean3.csv", tmp / "semi.csv"))
    )
    write(
        tmp / "tab.csv",
        f[:3],
        r[:3],
        sep="\t",
        head=["Hit", "Time [s]", "Force [N]", "Acceleration [m/s²]"],
    )
    rows.append(
        ("tab, units in brackets", frf_case(tmp, "tab", tmp / "clean3.csv", tmp / "tab.csv"))
    )
    text = (tmp / "clean3.csv").read_text()
    (tmp / "cut.csv").write_text(text[: len(text) - 7])
    rows.append(
        (
            "CSV cut inside the last number",
            frf_case(tmp, "cut", tmp / "clean3.csv", tmp / "cut.csv"),
        )
    )
    from robovib.io import HammerRecording, write_recording_uff

    write_recording_uff(
        tmp / "rec.uff", HammerRecording(np.array(f[:3]), np.array(r[:3]), FS, "acceleration", "x")
    )
    u = (tmp / "rec.uff").read_text()
    (tmp / "cutrec.uff").write_text(u[: int(0.7 * len(u))])
    (tmp / "cutnum.uff").write_text(u[: u.rstrip().rfind("-1") - 25])
    rows.append(("UFF cut mid-record", frf_case(tmp, "cu1", tmp / "rec.uff", tmp / "cutrec.uff")))
    rows.append(
        ("UFF cut inside a number", frf_case(tmp, "cu2", tmp / "rec.uff", tmp / "cutnum.uff"))
    )
    head = "file,direction,x_mm,y_mm,z_mm,rz_deg\n"
    write(tmp / "other.csv", f[1:4], r[1:4])
    (tmp / "copy.csv").write_bytes((tmp / "clean3.csv").read_bytes())
    mans = {
        "manifest: duplicated row": "clean3.csv,x,2400,0,325,0\n" * 2,
        "manifest: same recording at two poses": "clean3.csv,x,2400,0,325,0\nclean3.csv,x,2500,0,325,0\n",
        "manifest: two recordings, same pose/direction/replicate": "clean3.csv,x,2400,0,325,0\nother.csv,x,2400,0,325,0\n",
        "manifest: same content at two poses (copied file)": "clean3.csv,x,2400,0,325,0\ncopy.csv,x,2500,0,325,0\n",
    }
    for k, (label, body) in enumerate(mans.items()):
        (tmp / f"m{k}.csv").write_text(head + body)
        code, msg = cli(
            "campaign", "process", tmp / f"m{k}.csv", "-o", tmp / f"o{k}", "--workers", "1"
        )
        rows.append((label, f"clear error: {msg[:150]}" if code else f"WORSE: exit 0 ({msg})"))
    (tmp / "mb.csv").write_bytes(
        b"\xef\xbb\xbf" + (head + "clean3.csv,x,2400,0,325,0\nother.csv,x,2500,0,325,0\n").encode()
    )
    code, msg = cli("campaign", "process", tmp / "mb.csv", "-o", tmp / "ob", "--workers", "1")
    rows.append(
        (
            "manifest saved by Excel as CSV UTF-8 (BOM)",
            "correct result: " + msg[-120:] if not code else f"ERROR {msg}",
        )
    )
    lines = [head.strip()]
    for k in range(4):
        fk, rk = hits(3, n, FS, 20 + k)
        write(tmp / f"p{k}.csv", fk, [x / 9.80665 for x in rk] if k == 1 else rk)
        lines.append(f"p{k}.csv,x,{2100 + 100 * k},0,325,0")
    (tmp / "mg.csv").write_text("\n".join(lines) + "\n")
    code, msg = cli("campaign", "process", tmp / "mg.csv", "-o", tmp / "og1", "--workers", "1")
    rows.append(
        (
            "campaign: one file of 4 in g labelled m/s^2",
            f"clear error: {short(msg, 190)}" if code else f"WORSE: exit 0 ({msg})",
        )
    )
    import json

    # a user who widens the FRF range (a stiffer robot): the campaign median still flags the row
    flags = [r["flags"] or "" for r in json.loads(CliRunner().invoke(app, [
        "campaign", "process", str(tmp / "mg.csv"), "-o", str(tmp / "og2"), "--workers", "1",
        "--compliance-range", "1e-8", "1e-3", "--json"
    ]).output)["rows"]]  # fmt: skip
    rows.append(
        (
            "  same, --compliance-range 1e-8 1e-3 (stiffer robot)",
            f"flagged row 2: {flags[1][:110]}"
            if "g labelled" in flags[1]
            else f"NOT FLAGGED {flags}",
        )
    )
    (tmp / "ms.csv").write_text(head + "clean3.csv,x,2400,0,325,0\ncutrec.uff,x,2500,0,325,0\n")
    code, msg = cli(
        "campaign", "process", tmp / "ms.csv", "-o", tmp / "os", "--workers", "1", "--skip-bad"
    )
    rows.append(
        (
            "campaign --skip-bad with a cut UFF",
            ("skipped with reason: " if "skipped line 3" in msg else "?: ") + msg[:200]
            if not code
            else f"error {msg}",
        )
    )
    width = max(len(a) for a, _ in rows)
    for a, b in rows:
        print(f"{a:<{width}}  {b}")
    overload_rates()
    frf_level_rates()
    return 0


def frf_level_rates() -> None:
    """The FRF peak-compliance check on real and simulated robots, clean and read in g."""
    from robovib.datasets import load_table_a1
    from robovib.frf import FRF, check_frf_level, impact_frf
    from robovib.sim import VirtualRobot, simulate_hammer_test

    a1 = load_table_a1(units="si")
    f = np.arange(5.0, 200.0, 0.25)
    ok = bad = n = 0
    peaks = []
    for d in "xyz":
        for fn, k, c in a1[
            [f"fn_{d}_hz", f"stiffness_{d}_n_per_m", f"damping_{d}_ns_per_m"]
        ].values:
            if not np.all(np.isfinite([fn, k, c])):
                continue
            w, wn = 2 * np.pi * f, 2 * np.pi * fn
            h = 1 / (k - k / wn**2 * w**2 + 1j * c * w)  # closed-form SDOF receptance
            n += 1
            peaks.append(np.abs(h).max())
            ok += check_frf_level(FRF(f, h)) is None
            bad += "g labelled" in (check_frf_level(FRF(f, h / 9.80665)) or "")
    print(f"\nFRF peak-compliance check (default {PlausibleRanges().peak_compliance_m_per_n} m/N):")
    print(f"  Table A1 modes (closed form, 5-200 Hz): peak {min(peaks):.3g}-{max(peaks):.3g} m/N;"
          f" pass {ok}/{n}; read in g: flagged 'g labelled' {bad}/{n}")  # fmt: skip
    robot, rng = VirtualRobot(), np.random.default_rng(1)
    ok = bad = n = 0
    peaks = []
    for k in range(30):
        if k % 3 == 2:
            coords, dom = (rng.uniform(0, 1.235),), "path"
        else:
            coords, dom = (
                (rng.uniform(2.1, 2.7), rng.uniform(-0.3, 0.6), rng.uniform(0, 180)),
                "workspace",
            )
        for d in "xyz":
            rec = simulate_hammer_test(robot, coords, d, domain=dom, n_hits=3, rng=k, duration_s=1.0,
                                       sample_rate_hz=(1280.0, 2048.0, 5120.0)[k % 3])  # fmt: skip
            frf = impact_frf(rec.forces, rec.responses, rec.sample_rate_hz, f_max_hz=200.0)
            frf = frf.frf.to_compliance(5.0)
            n += 1
            peaks.append(np.abs(frf.values).max())
            ok += check_frf_level(frf) is None
            g = FRF(frf.frequency_hz, frf.values / 9.80665)
            bad += "g labelled" in (check_frf_level(g) or "")
    print(f"  virtual robot, simulated hammer tests (1 s, 3 hits, 30 poses x 3 directions):"
          f" peak {min(peaks):.3g}-{max(peaks):.3g} m/N; pass {ok}/{n}; read in g: flagged {bad}/{n}")  # fmt: skip


def overload_rates() -> None:
    """False overloads on simulated (never clipped) hits; detection on clipped pulses."""
    from robovib.frf import overload_reason
    from robovib.sim import VirtualRobot, simulate_hammer_test

    robot, rng = VirtualRobot(), np.random.default_rng(0)
    n = false = 0
    for k in range(20):
        pose = (rng.uniform(2.1, 2.55), rng.uniform(-0.3, 0.6), rng.uniform(0, 180))
        for d in "xyz":
            rec = simulate_hammer_test(robot, pose, d, n_hits=3, rng=k, duration_s=1.0,
                                       sample_rate_hz=(1280.0, 2048.0, 5120.0)[k % 3])  # fmt: skip
            for x in (*rec.forces, *rec.responses):
                n += 1
                false += overload_reason(x) is not None
    print(f"\nfalse overloads on simulated hits (forces and responses): {false} of {n} channels")
    print("clipped half-sine pulses (500 N, 2 ms), detected / tried, by plateau length [samples]:")
    found: dict = {}
    for fs in (1000.0, 2048.0, 5120.0, 10240.0):
        for level in (0.5, 0.7, 0.9):
            for seed in range(10):
                r = np.random.default_rng(seed)
                x = pulse(round(0.5 * fs), fs, 0.05 + r.uniform(0, 1 / fs), 2e-3, 500.0)
                lim = level * x.max()
                c = np.minimum(x, lim)
                plateau = int(np.sum(c >= lim))
                noisy = c + r.normal(size=c.size) * 0.002 * lim
                key = min(plateau, 5)
                e, m, t = found.get(key, (0, 0, 0))
                found[key] = (e + (overload_reason(c) is not None),
                              m + (overload_reason(noisy) is not None), t + 1)  # fmt: skip
    for key in sorted(found):
        e, m, t = found[key]
        print(f"  plateau {key}{'+' if key == 5 else ' '}: exact {e}/{t}, with 0.2 % noise {m}/{t}")


if __name__ == "__main__":
    sys.exit(main())
