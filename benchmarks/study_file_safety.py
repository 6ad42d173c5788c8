"""Sweep of bad and hostile input files over the command line (issue 38): every case ends in
one clear error naming the file, never a hang, a raw exception text or a lost file.

Run: ``python benchmarks/study_file_safety.py`` (about 3 minutes on one core). It builds a small
virtual campaign and its pose model in a temporary folder, writes the bad inputs next to them
(FIFOs, /dev/zero, links, truncated and mislabelled tables, zero FRFs ...), runs each case
in-process with a 25 s alarm and a 4 GiB address-space limit, and prints one line per case:

``case | verdict | the last error line`` with the verdict ``clear`` (one ``error:`` line that
names a file or option), ``exit 0``, ``raw message`` (an exception's own text), ``hang`` or
``special file replaced`` (an output FIFO or link that is no longer one).
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import signal
import stat
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CASES = """
# model fit / modal tables
model-fit-norow | model fit modal_norow.csv -o out.h5
model-fit-const | model fit modal_const.csv -o out.h5
model-fit-nan | model fit modal_nan.csv -o out.h5
model-fit-text | model fit modal_text.csv -o out.h5
model-fit-3rows | model fit modal_3rows.csv -o out.h5
model-fit-onepose | model fit modal_onepose.csv -o out.h5
model-fit-nodir | model fit modal_nodir.csv -o out.h5
model-fit-nofn | model fit modal_nofn.csv -o out.h5
model-fit-negk | model fit modal_negk.csv -o out.h5
model-fit-xonly | model fit modal_xonly.csv -o out.h5
model-fit-baddir | model fit modal_baddir.csv -o out.h5
model-fit-textpose | model fit modal_textpose.csv -o out.h5
model-fit-junk | model fit junk.csv -o out.h5
model-fit-h5 | model fit model.h5 -o out.h5
model-fit-badinputs | model fit modal.csv -o out.h5 --inputs x_mm,q_mm
model-fit-emptyinputs | model fit modal.csv -o out.h5 --inputs ,
model-fit-out-is-input | model fit modal.csv -o modal.csv
model-fit-out-fifo | model fit modal.csv -o fifo.h5
model-fit-out-link | model fit modal.csv -o link.h5
model-fit-plot-nosuffix | model fit modal.csv -o out.h5 --plot outplot
model-fit-plot-badsuffix | model fit modal.csv -o out.h5 --plot out.xyz
model-fit-out-txt | model fit modal.csv -o out.txt
# pose model inputs
gpr-model-fifo | gpr predict --model fifo.h5 --x 2400 --y 0 --rz 45
gpr-model-csv | gpr predict --model modal.csv --x 2400 --y 0 --rz 45
gpr-model-text-h5 | gpr predict --model text.h5 --x 2400 --y 0 --rz 45
gpr-model-empty | gpr predict --model empty.h5 --x 2400 --y 0 --rz 45
gpr-model-other | gpr predict --model other.h5 --x 2400 --y 0 --rz 45
gpr-model-tagged-empty | gpr predict --model tagged_bad.h5 --x 2400 --y 0 --rz 45
gpr-model-frfs | gpr predict --model frfs.h5 --x 2400 --y 0 --rz 45
gpr-model-dir | gpr predict --model sub --x 2400 --y 0 --rz 45
gpr-model-devzero | gpr predict --model /dev/zero --x 2400 --y 0 --rz 45
mill-predict-model-tagged | mill predict --model tagged_bad.h5 --x 2400 --y 0 --rz 45
report-model-tagged | report model tagged_bad.h5 -o out.html
report-model-nosuffix | report model model.h5 -o outreport
report-model-fifo-out | report model model.h5 -o fifo.csv
# next poses
next-nocol | model next-poses --model model.h5 --candidates poses_nocol.csv
next-nan | model next-poses --model model.h5 --candidates poses_nan.csv
next-hdr | model next-poses --model model.h5 --candidates poses_hdr.csv
next-one-k5 | model next-poses --model model.h5 --candidates poses_one.csv --k 5
next-junk | model next-poses --model model.h5 --candidates junk.csv
next-fifo | model next-poses --model model.h5 --candidates fifo.csv
next-out | model next-poses --model model.h5 --candidates poses_out.csv
next-plot-nosuffix | model next-poses --model model.h5 --candidates poses.csv --plot np
# cuts
lobes-cuts-hdr | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --cuts cuts_hdr.csv
lobes-cuts-neg | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --cuts cuts_neg.csv
lobes-cuts-maybe | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --cuts cuts_maybe.csv
lobes-cuts-nocol | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --cuts cuts_nocol.csv
lobes-cuts-short | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --cuts cuts_short.csv
lobes-cuts-junk | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --cuts junk.csv
lobes-cuts-empty | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --cuts empty.csv
lobes-cuts-fifo | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --cuts fifo.csv
lobes-cuts-devzero | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --cuts /dev/zero
lobes-cuts-missing | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --cuts nope.csv
lobes-plot-nosuffix | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --plot lobesplot
lobes-plot-badsuffix | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --plot lobes.xyz
lobes-plot-fifo | mill lobes --mode x:30,1e7,0.05 --rpm-range 1000:2000:5 --plot fifo.csv
lobes-mode-neg | mill lobes --mode x:30,-1e7,0.05 --rpm-range 1000:2000:5
lobes-mode-zeta0 | mill lobes --mode x:30,1e7,0 --rpm-range 1000:2000:5
# lobes --frf
lobes-frf-modal | mill lobes --frf modal.csv --rpm-range 1000:2000:5
lobes-frf-model | mill lobes --frf model.h5 --rpm-range 1000:2000:5
lobes-frf-rec | mill lobes --frf hammer.uff --rpm-range 1000:2000:5
lobes-frf-one | mill lobes --frf frf_one.csv --rpm-range 1000:2000:5
lobes-frf-zero | mill lobes --frf frf_zero.csv --rpm-range 1000:2000:5
lobes-frf-mag | mill lobes --frf frf_mag.csv --rpm-range 1000:2000:5
lobes-frf-fifo | mill lobes --frf fifo.h5 --rpm-range 1000:2000:5
lobes-frf-junk | mill lobes --frf junk.h5 --rpm-range 1000:2000:5
lobes-frf-txt | mill lobes --frf rec.txt --rpm-range 1000:2000:5
# modal fit
modal-one | modal fit frf_one.csv
modal-dec | modal fit frf_dec.csv
modal-zero | modal fit frf_zero.csv
modal-noimag | modal fit frf_noimag.csv
modal-nan | modal fit frf_nan.csv
modal-mag | modal fit frf_mag.csv
modal-const | modal fit frf_const.csv
modal-rec | modal fit hammer.uff
modal-model | modal fit model.h5
modal-modal-csv | modal fit modal.csv
modal-txt | modal fit rec.txt
modal-fifo | modal fit fifo.csv
modal-plot-nosuffix | modal fit frf.csv --plot mplot
modal-modes-one | modal fit frf_one.csv --modes
modal-band-out | modal fit frf.csv --band 500 600
# frf compute
frf-one | frf compute rec_one.csv -o out.h5
frf-two | frf compute rec_two.csv -o out.h5
frf-nan | frf compute rec_nan.csv -o out.h5
frf-back | frf compute rec_back.csv -o out.h5
frf-zero | frf compute rec_zero.csv -o out.h5
frf-nodir | frf compute rec_nodir.csv -o out.h5
frf-hdr | frf compute rec_hdr.csv -o out.h5
frf-txt | frf compute rec.txt -o out.h5
frf-junk-uff | frf compute junk.uff -o out.h5
frf-junk-csv | frf compute junk.csv -o out.h5
frf-fifo | frf compute fifo.uff -o out.h5
frf-devzero | frf compute /dev/zero -o out.h5
frf-out-txt | frf compute hammer.uff -o out.txt
frf-out-nosuffix | frf compute hammer.uff -o outfrf
frf-out-fifo | frf compute hammer.uff -o fifo.h5
frf-out-link | frf compute hammer.uff -o link.h5
frf-modal | frf compute modal.csv -o out.h5
# mill predict --forces
predict-forces-one | mill predict --x 2400 --y 0 --rz 45 --forces forces_one.csv
predict-forces-back | mill predict --x 2400 --y 0 --rz 45 --forces forces_back.csv
predict-forces-nocol | mill predict --x 2400 --y 0 --rz 45 --forces forces_nocol.csv
predict-forces-const-t | mill predict --x 2400 --y 0 --rz 45 --forces forces_const_t.csv
predict-forces-junk | mill predict --x 2400 --y 0 --rz 45 --forces junk.csv
predict-forces-fifo | mill predict --x 2400 --y 0 --rz 45 --forces fifo.csv
# hybrid oma
oma-short | hybrid oma mr_short.csv -o out.h5
oma-nocol | hybrid oma mr_nocol.csv -o out.h5
oma-const-t | hybrid oma mr_const_t.csv -o out.h5
oma-junk | hybrid oma junk.csv -o out.h5
oma-fifo | hybrid oma fifo.csv -o out.h5
oma-out-txt | hybrid oma milling_record.csv -o out.txt
hybrid-fit-model | hybrid fit model.h5 -o out.h5
hybrid-fit-frfs | hybrid fit frfs.h5 -o out.h5
hybrid-fit-csv | hybrid fit frf.csv -o out.h5
hybrid-predict-posemodel | hybrid predict model.h5 --path-s 0.5
# control schedule
sched-one | control schedule --path-file sched_one.csv
sched-neg | control schedule --path-file sched_neg.csv
sched-nocol | control schedule --path-file sched_nocol.csv
sched-dup | control schedule --path-file sched_dup.csv
sched-junk | control schedule --path-file junk.csv
sched-fifo | control schedule --path-file fifo.csv
sched-model-csv | control schedule --start 2400,-200,45 --end 2400,200,45 --model modal.csv
# robot identify
identify-one | robot identify tests_one.csv
identify-nocol | robot identify tests_nocol.csv
identify-fifo | robot identify fifo.csv
# campaign
camp-dir | campaign process man_dir.csv -o cout --workers 1
camp-txt | campaign process man_txt.csv -o cout --workers 1
camp-empty | campaign process man_empty.csv -o cout --workers 1
camp-sens0 | campaign process man_sens0.csv -o cout --workers 1
camp-nocol | campaign process man_nocol.csv -o cout --workers 1
camp-fifo-rec | campaign process man_fifo.csv -o cout --workers 1
camp-zero-rec | campaign process man_zero.csv -o cout --workers 1
camp-h5-rec | campaign process man_h5.csv -o cout --workers 1
camp-junk | campaign process junk.csv -o cout --workers 1
camp-out-file | campaign process man_h5.csv -o modal.csv --workers 1
camp-modes-band-bad | campaign process man_txt.csv -o cout --modes-band 5
# sim
simcamp-nocol | sim campaign --poses poses_nocol.csv -o scamp --hits 1 --duration-s 0.5
simcamp-out | sim campaign --poses poses_out.csv -o scamp --hits 1 --duration-s 0.5
simcamp-nan | sim campaign --poses poses_nan.csv -o scamp --hits 1 --duration-s 0.5
simcamp-scatter | sim campaign --poses poses_one.csv -o scamp --hits 1 --duration-s 0.5 --scatter 0.1,0.1
simcamp-out-file | sim campaign --poses poses_one.csv -o modal.csv --hits 1 --duration-s 0.5
simhammer-devnull | sim hammer -o /dev/null --hits 1 --duration-s 0.5
simhammer-link | sim hammer -o link.uff --hits 1 --duration-s 0.5
simhammer-fifo | sim hammer -o fifo.csv --hits 1 --duration-s 0.5
simhammer-out | sim hammer -o out.uff --hits 1 --duration-s 0.5 --x 99999
simmill-fifo | sim mill -o fifo.csv --x1 2110
# map
map-out-nosuffix | mill map --nx 2 --ny 2 -o mapout
map-out-txt | mill map --nx 2 --ny 2 -o map.txt
map-plot-nosuffix | mill map --nx 2 --ny 2 --plot mapplot
map-sched-bad | mill map --nx 2 --ny 2 --scheduler tcp://127.0.0.1:1
map-sched-word | mill map --nx 2 --ny 2 --scheduler bogus
camp-out-is-manifest | campaign process mdir/modal.csv -o mdir --workers 1
simcamp-onto-poses | sim campaign --poses truth.csv -o . --hits 1 --duration-s 0.5
frf-out-is-input | frf compute hammer.uff -o hammer.uff
modal-plot-is-input | modal fit frf.csv --plot frf.csv
# models with other inputs
gpr-model2 | gpr predict --model model2.h5 --x 2400 --y 0 --rz 45
gpr-model2-noz | gpr predict --model model4.h5 --x 2400 --y 0 --rz 45
lobes-model2 | mill lobes --model model2.h5 --x 2400 --y 0 --rz 45 --rpm-range 1000:2000:5
lobes-model2-samples | mill lobes --model model2.h5 --x 2400 --y 0 --rz 45 --rpm-range 1000:2000:5 --samples 10
predict-model2 | mill predict --model model2.h5 --x 2400 --y 0 --rz 45
predict-model4 | mill predict --model model4.h5 --x 2400 --y 0 --rz 45
map-model2 | mill map --model model2.h5 --nx 2 --ny 2
map-model4 | mill map --model model4.h5 --nx 2 --ny 2
gains-model2 | control gains --model model2.h5 --x 2400 --y 0 --rz 45
sched-model2 | control schedule --model model2.h5 --start 2400,-200,45 --end 2400,200,45
sched-model4 | control schedule --model model4.h5 --start 2400,-200,45 --end 2400,200,45
next-model4 | model next-poses --model model4.h5 --candidates poses.csv
report-lobes-model2 | report lobes --model model2.h5 --x 2400 --y 0 --rz 45 -o rl.html
report-model-frfmodel | report model hy/model.h5 -o rm.html
# hybrid mismatches
hy-update-grid | hybrid update hy/model.h5 hy/oma_grid.h5 -o out.h5
hy-update-nopath | hybrid update hy/model.h5 hy/oma_nopath.h5 -o out.h5
hy-update-posemodel | hybrid update model.h5 hy/oma.h5 -o out.h5
hy-predict-measured-grid | hybrid predict hy/model.h5 --path-s 0.6 --measured hy/oma_grid.h5
hy-predict-measured-modal | hybrid predict hy/model.h5 --path-s 0.6 --measured modal.csv
hy-predict-xy | hybrid predict hy/model.h5 --x 2400 --y 0 --rz 45
hy-fit-oma | hybrid fit hy/oma.h5 -o out.h5
hy-fit-one | hybrid fit hy/frf.h5 -o out.h5
hy-fit-mixed | hybrid fit hy/ema.h5 hy/omay.h5 -o out.h5
hy-oma-rec | hybrid oma hy/forces.csv -o out.h5
control-sim-model | control simulate milling --model modal.csv
lobes-frf-ema-sdm | mill lobes --frf hy/ema.h5 --rpm-range 1000:2000:5
lobes-frf-cross | mill lobes --frf frfs.h5 --rpm-range 1000:2000:5
modal-fit-frfs-modes | modal fit hy/inverted.h5 --modes
frf-compute-recclip | frf compute hy/recclip.uff -o out.h5
identify-sched | robot identify hy/sched.csv
# more FIFO / special-file cases
lobes-model-fifo | mill lobes --model fifo.h5 --x 2400 --y 0 --rz 45 --rpm-range 1000:2000:5
gains-model-fifo | control gains --model fifo.h5 --x 2400 --y 0 --rz 45
report-model-fifo | report model fifo.h5 -o r.html
hy-predict-fifo | hybrid predict fifo.h5 --path-s 0.5
hy-update-fifo | hybrid update hy/model.h5 fifo.h5 -o out.h5
hy-fit-fifo | hybrid fit fifo.h5 -o out.h5
hy-fit-devzero | hybrid fit /dev/zero -o out.h5
frf-compute-fifo-csv | frf compute fifo.csv -o out.h5
model-fit-fifo | model fit fifo.csv -o out.h5
model-fit-devzero | model fit /dev/zero -o out.h5
model-fit-dir | model fit sub -o out.h5
examples-to-link | examples --to exlink
examples-to-fifo | examples --to exfifo
report-model-out-link | report model model.h5 -o link.h5
map-out-link | mill map --nx 2 --ny 2 -o link.nc
hy-oma-out-fifo | hybrid oma milling_record.csv -o fifo.h5
camp-process-rerun-stale | campaign process mdir2/man.csv -o mdir2 --workers 1
"""

RAW = ("unexpected", "Format '", "outputs [", "Geometric", "SVD did", "Initial guess",
       "zero-size array", "could not convert", "Errno", "codec can't", "field larger")  # fmt: skip
FIFOS = ("fifo.uff", "fifo.csv", "fifo.h5")


def build(W: Path) -> None:
    """The valid inputs (a virtual campaign, its modal table and model) and the bad ones."""
    import h5py
    import pandas as pd

    from robovib.campaign import fit_campaign_table, process_campaign, save_pose_model
    from robovib.datasets import copy_examples
    from robovib.sim import simulate_campaign

    W.mkdir(parents=True, exist_ok=True)
    copy_examples(W)
    poses = pd.read_csv(W / "poses.csv").iloc[:12]
    camp = simulate_campaign(poses, W / "camp", rng=0, n_hits=2)
    process_campaign(camp.manifest, W / "camp" / "out", n_workers=1)
    shutil.copy(W / "camp" / "out" / "modal.csv", W / "modal.csv")
    shutil.copy(W / "camp" / "out" / "frfs.h5", W / "frfs.h5")
    save_pose_model(fit_campaign_table(W / "modal.csv"), W / "model.h5")
    for inputs, name in (("x_mm,y_mm", "model2.h5"), ("x_mm,y_mm,z_mm,rz_deg", "model4.h5")):
        save_pose_model(fit_campaign_table(W / "modal.csv", inputs=inputs.split(",")), W / name)
    m = pd.read_csv(W / "modal.csv")
    m.drop(columns=["row"]).to_csv(W / "modal_norow.csv", index=False)
    c = m.copy()
    c["damping_ratio"] = 0.05
    c["damping_ns_per_m"] = 1000.0
    c.to_csv(W / "modal_const.csv", index=False)
    c = m.copy()
    c.loc[3, "stiffness_n_per_m"] = np.nan
    c.to_csv(W / "modal_nan.csv", index=False)
    c = m.copy()
    c["fn_hz"] = c["fn_hz"].astype(object)
    c.loc[2, "fn_hz"] = "abc"
    c.to_csv(W / "modal_text.csv", index=False)
    m.iloc[:3].to_csv(W / "modal_3rows.csv", index=False)
    c = m.copy()
    c["x_mm"] = 2400.0
    c["y_mm"] = 0.0
    c["rz_deg"] = 45.0
    c.to_csv(W / "modal_onepose.csv", index=False)
    m.drop(columns=["direction"]).to_csv(W / "modal_nodir.csv", index=False)
    m.drop(columns=["fn_hz"]).to_csv(W / "modal_nofn.csv", index=False)
    c = m.copy()
    c.loc[0, "stiffness_n_per_m"] = -1e6
    c.to_csv(W / "modal_negk.csv", index=False)
    m[m.direction == "x"].to_csv(W / "modal_xonly.csv", index=False)
    c = m.copy()
    c["direction"] = "q"
    c.to_csv(W / "modal_baddir.csv", index=False)
    c = m.copy()
    c["x_mm"] = "a"
    c.to_csv(W / "modal_textpose.csv", index=False)
    (W / "cuts_hdr.csv").write_text("spindle_rpm,depth_mm,result\n")
    (W / "cuts_neg.csv").write_text("spindle_rpm,depth_mm,result\n1500,-2,stable\n")
    (W / "cuts_maybe.csv").write_text("spindle_rpm,depth_mm,result\n1500,2,maybe\n")
    (W / "cuts_nocol.csv").write_text("spindle_rpm,result\n1500,stable\n")
    (W / "cuts_short.csv").write_text("spindle_rpm,depth_mm,result\n1500,2\n")
    (W / "junk.bin").write_bytes(bytes(range(256)) * 8)
    (W / "junk.csv").write_bytes(bytes(range(256)) * 8)
    (W / "junk.h5").write_bytes(bytes(range(256)) * 8)
    (W / "junk.uff").write_bytes(bytes(range(256)) * 8)
    (W / "text.h5").write_text("x_mm,y_mm\n1,2\n")
    (W / "empty.csv").write_text("")
    (W / "empty.h5").write_bytes(b"")
    (W / "poses_nocol.csv").write_text("x_mm,y_mm\n2400,0\n")
    (W / "poses_nan.csv").write_text("x_mm,y_mm,rz_deg\n2400,nan,45\n")
    (W / "poses_hdr.csv").write_text("x_mm,y_mm,rz_deg\n")
    (W / "poses_out.csv").write_text("x_mm,y_mm,rz_deg\n99999,0,45\n")
    (W / "poses_one.csv").write_text("x_mm,y_mm,rz_deg\n2400,0,45\n")
    (W / "frf_one.csv").write_text("frequency_hz,x_real_um_per_n,x_imag_um_per_n\n10,1,1\n")
    (W / "frf_dec.csv").write_text(
        "frequency_hz,x_real_um_per_n,x_imag_um_per_n\n10,1,1\n9,1,1\n8,1,1\n"
    )
    (W / "frf_zero.csv").write_text(
        "frequency_hz,x_real_um_per_n,x_imag_um_per_n\n"
        + "".join(f"{f},0,0\n" for f in range(1, 60))
    )
    (W / "frf_noimag.csv").write_text("frequency_hz,x_real_um_per_n\n10,1\n11,1\n")
    (W / "frf_nan.csv").write_text(
        "frequency_hz,x_real_um_per_n,x_imag_um_per_n\n10,nan,1\n11,1,1\n"
    )
    (W / "frf_mag.csv").write_text(
        "frequency_hz,x_abs_um_per_n\n" + "".join(f"{f},1\n" for f in range(1, 60))
    )
    (W / "frf_const.csv").write_text(
        "frequency_hz,x_real_um_per_n,x_imag_um_per_n\n"
        + "".join(f"{f},1,1\n" for f in range(1, 60))
    )
    (W / "rec_one.csv").write_text("time_s,force_n,acceleration_x_m_per_s2\n0,1,1\n")
    (W / "rec_two.csv").write_text("time_s,force_n,acceleration_x_m_per_s2\n0,1,1\n0.001,0,0\n")
    (W / "rec_nan.csv").write_text(
        "time_s,force_n,acceleration_x_m_per_s2\n0,1,1\n0.001,nan,0\n0.002,0,0\n"
    )
    (W / "rec_back.csv").write_text(
        "time_s,force_n,acceleration_x_m_per_s2\n0,1,1\n0.002,0,0\n0.001,0,0\n"
    )
    (W / "rec_zero.csv").write_text(
        "time_s,force_n,acceleration_x_m_per_s2\n"
        + "".join(f"{i / 1000},0,0\n" for i in range(3000))
    )
    (W / "rec_nodir.csv").write_text(
        "time_s,force_n,acceleration_m_per_s2\n"
        + "".join(f"{i / 1000},{1 if i == 5 else 0},0\n" for i in range(3000))
    )
    (W / "rec_hdr.csv").write_text("time_s,force_n,acceleration_x_m_per_s2\n")
    (W / "rec.txt").write_text("hello\n")
    (W / "forces_one.csv").write_text("time_s,force_x_n,force_y_n,force_z_n\n0,1,1,1\n")
    (W / "forces_back.csv").write_text(
        "time_s,force_x_n,force_y_n,force_z_n\n0,1,1,1\n0.002,1,1,1\n0.001,1,1,1\n"
    )
    (W / "forces_nocol.csv").write_text("time_s,force_x_n\n0,1\n0.001,1\n")
    (W / "forces_const_t.csv").write_text(
        "time_s,force_x_n,force_y_n,force_z_n\n0,1,1,1\n0,1,1,1\n0,1,1,1\n"
    )
    mr = pd.read_csv(W / "milling_record.csv")
    mr.iloc[:50].to_csv(W / "mr_short.csv", index=False)
    mr.drop(columns=[mr.columns[-1]]).to_csv(W / "mr_nocol.csv", index=False)
    c = mr.copy()
    c.iloc[:, 0] = 0.0
    c.to_csv(W / "mr_const_t.csv", index=False)
    (W / "sched_one.csv").write_text("s_m,fn_hz,stiffness_n_per_m,damping_ratio\n0.5,16,2e6,0.05\n")
    (W / "sched_neg.csv").write_text(
        "s_m,fn_hz,stiffness_n_per_m,damping_ratio\n0.5,16,-2e6,0.05\n0.6,16,2e6,0.05\n"
    )
    (W / "sched_nocol.csv").write_text("s_m,fn_hz\n0.5,16\n")
    (W / "sched_dup.csv").write_text(
        "s_m,fn_hz,stiffness_n_per_m,damping_ratio\n0.5,16,2e6,0.05\n0.5,16,2e6,0.05\n"
    )
    (W / "tests_one.csv").write_text(
        "a1_deg,a2_deg,a3_deg,a4_deg,a5_deg,a6_deg,fx_n,fy_n,fz_n,mx_nm,my_nm,mz_nm,dx_m,dy_m,dz_m\n0,-90,90,0,10,0,1,1,1,0,0,0,1e-6,1e-6,1e-6\n"
    )
    (W / "tests_nocol.csv").write_text("a1_deg,fx_n\n0,1\n")
    (W / "man_dir.csv").write_text("file,direction,x_mm,y_mm,z_mm,rz_deg\nsub,x,2400,0,325,45\n")
    (W / "sub").mkdir(exist_ok=True)
    (W / "man_txt.csv").write_text(
        "file,direction,x_mm,y_mm,z_mm,rz_deg\nrec.txt,x,2400,0,325,45\n"
    )
    (W / "man_empty.csv").write_text(
        "file,direction,x_mm,y_mm,z_mm,rz_deg\nempty.csv,x,2400,0,325,45\n"
    )
    (W / "man_sens0.csv").write_text(
        "file,direction,x_mm,y_mm,z_mm,rz_deg,force_sensitivity_mv_per_n\nhammer.uff,x,2400,0,325,45,0\n"
    )
    (W / "man_nocol.csv").write_text("file,x_mm\nhammer.uff,2400\n")
    (W / "man_fifo.csv").write_text(
        "file,direction,x_mm,y_mm,z_mm,rz_deg\nfifo.uff,x,2400,0,325,45\n"
    )
    (W / "man_zero.csv").write_text(
        "file,direction,x_mm,y_mm,z_mm,rz_deg\n/dev/zero,x,2400,0,325,45\n"
    )
    (W / "man_h5.csv").write_text(
        "file,direction,x_mm,y_mm,z_mm,rz_deg\nmodel.h5,x,2400,0,325,45\n"
    )
    for n in ("fifo.uff", "fifo.csv", "fifo.h5"):
        if not (W / n).exists():
            os.mkfifo(W / n)
    with h5py.File(W / "other.h5", "w") as h:
        h["x"] = np.arange(3)
    with h5py.File(W / "tagged_bad.h5", "w") as h:
        h.attrs["format"] = "robovib-pose-model"
        h.attrs["format_version"] = 1
    os.symlink("model.h5", W / "link.h5")
    os.symlink("model.h5", W / "link.uff")
    os.symlink("model.h5", W / "link.nc")
    shutil.copy(W / "poses_one.csv", W / "truth.csv")
    (W / "mdir").mkdir()
    (W / "mdir" / "modal.csv").write_text(
        "file,direction,x_mm,y_mm,z_mm,rz_deg\n../hammer.uff,x,2400,0,325,45\n"
    )
    (W / "mdir2").mkdir()
    (W / "mdir2" / "man.csv").write_text(
        "file,direction,x_mm,y_mm,z_mm,rz_deg\n../hammer.uff,x,2400,0,325,45\n"
    )
    (W / "mdir2" / "modes.csv").write_text("an earlier run's modes table\n")
    (W / "exlink").mkdir()
    os.symlink("../cuts.csv", W / "exlink" / "cuts.csv")
    (W / "exfifo").mkdir()
    os.mkfifo(W / "exfifo" / "cuts.csv")
    hy = W / "hy"
    hy.mkdir()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_cli_bad_input import _make_inputs

    from robovib.frf import FRF
    from robovib.io import write_frfs
    from robovib.modal import ModalParameters

    _make_inputs(hy)
    f2 = np.arange(1.0, 50.0, 0.5)
    m = ModalParameters(9.0, 1.2e6, 0.15)
    write_frfs(hy / "oma_grid.h5", [FRF(f2, m.compliance(f2), direction="x", source="OMA",
                                        meta={"path_s_m": 0.6})])  # fmt: skip
    write_frfs(hy / "oma_nopath.h5", [FRF(f2, m.compliance(f2), direction="x", source="OMA")])


def _isfifo(p: str) -> bool:
    return stat.S_ISFIFO(os.lstat(p).st_mode)


def fresh(template: Path, d: Path) -> None:
    """A copy of the inputs for one case (FIFOs made anew, never read)."""
    shutil.copytree(template, d, symlinks=True,
                    ignore=lambda dd, names: [n for n in names if _isfifo(os.path.join(dd, n))])  # fmt: skip
    for root, _dirs, names in os.walk(template):
        for n in names:
            q = os.path.join(root, n)
            if _isfifo(q):
                os.mkfifo(d / os.path.relpath(q, template))
    for n in FIFOS:
        if not (d / n).exists():
            os.mkfifo(d / n)


class _Alarm(Exception):
    pass


def _alarm(*_):
    raise _Alarm()


def run_cases(template: Path, work: Path, only=()) -> dict:
    from typer.testing import CliRunner

    from robovib.cli import app

    signal.signal(signal.SIGALRM, _alarm)
    results = {}
    for line in CASES.strip().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        cid, argv = (s.strip() for s in line.split("|", 1))
        if only and cid not in only:
            continue
        d = work / cid
        fresh(template, d)
        os.chdir(d)
        specials = {
            n: os.lstat(n).st_mode
            for n in ("fifo.h5", "fifo.csv", "link.h5", "link.uff", "link.nc")
        }
        t0 = time.perf_counter()
        signal.alarm(25)
        try:
            r = CliRunner().invoke(app, argv.split())
            signal.alarm(0)
            errs = [x.strip() for x in r.output.splitlines() if x.lower().startswith("error")]
            last = errs[-1] if errs else (r.output.strip().splitlines() or [""])[-1]
            verdict = "exit 0" if r.exit_code == 0 else "clear"
            if any(w in last for w in RAW) or "Traceback" in r.output:
                verdict = "raw message"
            if any(os.lstat(n).st_mode != m for n, m in specials.items() if os.path.lexists(n)):
                verdict = "special file replaced"
        except _Alarm:
            verdict, last = "hang", "no answer within 25 s"
        results[cid] = {
            "verdict": verdict,
            "message": last,
            "s": round(time.perf_counter() - t0, 1),
        }
        if cid == "camp-process-rerun-stale":
            results[cid]["message"] += " | folder: " + ",".join(sorted(os.listdir("mdir2")))
        os.chdir(work)
    return results


def main() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
    with tempfile.TemporaryDirectory() as tmp:
        template, work = Path(tmp) / "inputs", Path(tmp) / "cases"
        build(template)
        work.mkdir()
        res = run_cases(template, work, set(sys.argv[1:]))
    counts: dict[str, int] = {}
    for cid, r in res.items():
        counts[r["verdict"]] = counts.get(r["verdict"], 0) + 1
        print(f"{cid} | {r['verdict']} | {r['message'][:160]}")
    print(json.dumps(counts))


if __name__ == "__main__":
    main()
