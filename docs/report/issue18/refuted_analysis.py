#!/usr/bin/env python3
"""Per-pixel effect of a correction round against the sim's truth (issue 18, session 14, val18b).

usage: refuted_analysis.py KEEP_SCENE_DIR TRUTH_DIR
KEEP_SCENE_DIR: `procam bench --keep DIR` output of one scene run with --method ensemble
  (holds ensemble-nocorr/ and ensemble/: proj_col_px.exr, resolved_in_round.png).
TRUTH_DIR: `procam sim --scene S --pattern white --out DIR` (proj_col.exr, lit.png).
Wrong = |column - truth| > 1 on lit pixels. "moved": valid in both, more than 2 columns
apart (the refuted pixels that took the round's column); "valid -> invalid": the refuted
pixels whose new column failed the merge's tests.
"""
import os, sys
os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
import cv2, numpy as np
def read(p):
    a = cv2.imread(p, cv2.IMREAD_UNCHANGED)
    if a is None: raise SystemExit("cannot read " + p)
    if a.ndim == 3: a = a[..., 0]
    return a
keep, gt = sys.argv[1], sys.argv[2]
t = read(gt + "/proj_col.exr"); lit = read(gt + "/lit.png") > 0
a = read(keep + "/ensemble-nocorr/proj_col_px.exr"); b = read(keep + "/ensemble/proj_col_px.exr")
rr = read(keep + "/ensemble/resolved_in_round.png")
va = np.isfinite(a) & lit; vb = np.isfinite(b) & lit
ra = va & (np.abs(a - t) <= 1); rb = vb & (np.abs(b - t) <= 1)
moved = va & vb & (np.abs(a - b) > 2)
lost = va & ~vb
gained = ~va & vb
print("first-pass valid %d wrong %d; after valid %d wrong %d" % (va.sum(), (va & ~ra).sum(), vb.sum(), (vb & ~rb).sum()))
print("moved >2 cols (valid->valid): %d  wrong->right %d  right->wrong %d  wrong->wrong %d  right->right %d" % (
    moved.sum(), (moved & ~ra & rb).sum(), (moved & ra & ~rb).sum(), (moved & ~ra & ~rb).sum(), (moved & ra & rb).sum()))
print("valid->invalid: %d (were wrong %d, right %d)" % (lost.sum(), (lost & ~ra).sum(), (lost & ra).sum()))
print("invalid->valid: %d (right %d, wrong %d)" % (gained.sum(), (gained & rb).sum(), (gained & ~rb).sum()))
same = va & vb & (np.abs(a - b) <= 2) & ((rr == 0))
print("unchanged by round (resolved_in 0, valid both): %d, identical value %d" % (same.sum(), (same & (a == b)).sum()))
