#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Issue 18, session 14: where the ensemble vote loses to one code, per pixel against the sim's truth.

usage: vote_analysis.py KEEP_DIR TRUTH_DIR [OBJECT_NAMES]

KEEP_DIR:  one `ensemble` run kept by `procam bench --keep` with
           `--param ensemble.code_maps=true --param ensemble.correction_rounds=0`
           (proj_col_px.exr, transport_class.png and the per-code maps
           proj_col_px_{gray,xor02,xor04,minsw}.exr of the same frames).
TRUTH_DIR: `procam sim --scene S --pattern white --out DIR` (proj_col.exr, lit.png, object.png).
OBJECT_NAMES: comma-separated names for object ids 1, 2, ... (scene file order).

Prints (README.md, "Session 14"):
  1. vote vs XOR-02 per object (wrong = |column - truth| > 1 on lit pixels);
  2. what the other codes say where XOR-02 is right and the vote wrong, and
     where XOR-02 is invalid and the vote wrong (the codes agreeing with the
     vote's value; whether XOR-02 tied for the largest support);
  3. candidate vote rules, *estimated* by leaving the output map's pixels
     invalid where a rule would (the refinement of neighbouring columns is not
     re-run): gross % and decoded change.
Needs numpy and OpenCV with OpenEXR (python3-numpy, python3-opencv).
"""
import collections
import os
import sys

os.environ["OPENCV_IO_ENABLE_OPENEXR"] = "1"
import cv2  # noqa: E402
import numpy as np  # noqa: E402

CODES = ("gray", "xor02", "xor04", "minsw")
GRAY, XOR02, XOR04, MINSW = range(4)


def read(path):
    a = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if a is None:
        raise SystemExit("cannot read " + path)
    return a[..., 0] if a.ndim == 3 else a


def main(argv):
    if len(argv) < 3:
        raise SystemExit(__doc__)
    keep, truth = argv[1], argv[2]
    names = argv[3].split(",") if len(argv) > 3 else []
    gc = read(truth + "/proj_col.exr")
    lit = read(truth + "/lit.png") > 0
    obj = read(truth + "/object.png")
    vote = read(keep + "/proj_col_px.exr")
    cls = read(keep + "/transport_class.png")
    code = [read(f"{keep}/proj_col_px_{k}.exr") for k in CODES]
    val = [np.isfinite(c) & lit for c in code]
    right = [v & (np.abs(c - gc) <= 1) for c, v in zip(code, val)]
    ev = np.isfinite(vote) & lit
    er = ev & (np.abs(vote - gc) <= 1)
    ew = ev & ~er

    def agree(a, b):
        return val[a] & val[b] & (np.abs(code[a] - code[b]) <= 1.0)

    def label(o):
        return names[o - 1] if 0 < o <= len(names) else f"object {o}"

    def rate(col):
        v = np.isfinite(col) & lit
        w = v & (np.abs(col - gc) > 1)
        return int(v.sum()), int(w.sum())

    V, W = rate(vote)
    XV, XW = rate(code[XOR02])
    print(f"vote: {W} wrong of {V} decoded = {100 * W / V:.3f} %; "
          f"XOR-02 map of the same frames: {XW} of {XV} = {100 * XW / XV:.3f} %")

    # 1. Vote vs XOR-02 per object.
    xv, xr = val[XOR02], right[XOR02]
    xw = xv & ~xr
    objs = [int(o) for o in np.unique(obj[lit])]
    print("\n| pixels | " + " | ".join(label(o) for o in objs) + " | all |")
    print("|---|" + "---:|" * (len(objs) + 1))
    for title, m in (("vote wrong, XOR-02 right", ew & xr), ("vote wrong, XOR-02 wrong", ew & xw),
                     ("vote wrong, XOR-02 invalid", ew & ~xv), ("vote right, XOR-02 wrong", er & xw),
                     ("vote invalid, XOR-02 wrong", ~ev & xw), ("vote right, XOR-02 invalid", er & ~xv),
                     ("vote invalid, XOR-02 right", ~ev & xr),
                     ("vote valid, no code right", ev & ~(right[0] | right[1] | right[2] | right[3]))):
        print(f"| {title} | " + " | ".join(f"{int((m & (obj == o)).sum()):,}" for o in objs) +
              f" | {int(m.sum()):,} |")

    # 2. What the other codes say where the vote is wrong and XOR-02 is not.
    support = np.zeros((4,) + vote.shape, int)
    for a in range(4):
        for b in range(a + 1, 4):
            ag = agree(a, b)
            support[a] += ag
            support[b] += ag
    best = support.max(0)
    for title, m in (("vote wrong, XOR-02 right", ew & xr), ("vote wrong, XOR-02 invalid", ew & ~xv)):
        sets = collections.Counter(
            "+".join(CODES[k] for k in range(4) if val[k][i] and abs(code[k][i] - vote[i]) <= 1)
            for i in zip(*np.nonzero(m)))
        tie = int((m & xv & (support[XOR02] == best)).sum())
        off = np.percentile(np.abs(vote - gc)[m], [10, 50, 90]) if m.any() else [0, 0, 0]
        print(f"\n{title}: {int(m.sum())}; codes agreeing with the vote's value: "
              + ", ".join(f"{k or 'none'} {n}" for k, n in sets.most_common(8)))
        print(f"  XOR-02 tied for the largest support (tie-break order chose another): {tie}; "
              f"classes {dict(sorted(collections.Counter(cls[m].tolist()).items()))}; "
              f"|vote - truth| 10/50/90 %: {off[0]:.1f} / {off[1]:.1f} / {off[2]:.1f} columns")

    # 3. Candidate rules (estimates: the output map's pixels left invalid).
    three = agree(GRAY, XOR04) & agree(GRAY, MINSW) & agree(XOR04, MINSW)
    dissent = three & xv & ~agree(XOR02, GRAY) & ~agree(XOR02, XOR04) & ~agree(XOR02, MINSW)
    pairs = sum(agree(a, b).astype(int) for a in range(4) for b in range(a + 1, 4))
    gray_xor_pair = (pairs == 1) & (agree(GRAY, XOR02) | agree(GRAY, XOR04))
    rules = (("C1: three agree, a valid XOR-02 dissents -> invalid", dissent),
             ("C3: XOR-02 invalid and fewer than three codes agree -> invalid", ~xv & ~three),
             ("C5: gray + an XOR code the only pair (third codes invalid) -> invalid", gray_xor_pair),
             ("C1 + C5", dissent | gray_xor_pair),
             ("C1 + C3", dissent | (~xv & ~three)),
             ("G: XOR-02 must be valid", ~xv))
    print(f"\n| rule | decoded change | gross % (was {100 * W / V:.4f}) | change (pp) |")
    print("|---|---:|---:|---:|")
    for title, m in rules:
        col = vote.copy()
        col[m & ev] = np.nan
        v2, w2 = rate(col)
        print(f"| {title} | {100 * (v2 - V) / V:+.3f} % | {100 * w2 / v2:.4f} | "
              f"{100 * w2 / v2 - 100 * W / V:+.4f} |")


if __name__ == "__main__":
    main(sys.argv)
