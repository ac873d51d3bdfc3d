#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Numbers of docs/report/real.md, "Averaging along the stripe, and an
image-level gate" (offline model, model.py beside this file).

usage: run.py real CAPTURE H       coverage / outliers / agreement, captures 0-4
       run.py sim FRAMES_DIR H     decoded / gross / added / wrong on a sim scene
       run.py gate real | FRAMES_DIR   F_noise: finest plane uncertain with a
                                       noise-set threshold, % of lit pixels

FRAMES_DIR holds one sim scene rendered frame by frame, one noise seed per
frame (seed 100 + i in a copy of configs/rigs/sim.json whose ../scenes
resolves), as white.png, black.png, gray_K.png, gray_K_inv.png (K = 0..10,
`procam sim --pattern gray:K[:inv]`, each frame's image.png), and
truth_col.tif (the white render's proj_col.exr as float TIFF, e.g.
`oiiotool proj_col.exr -d float -o truth_col.tif`) and that render's lit.png.
The table rows "max(k sigma_avg, 0.1 C)" and "only where k sigma_d >= 0.1 C"
are model.stripe_rule(..., with_c=True) and (..., gate=1).
"""
import sys
import numpy as np
from PIL import Image
import model as M


def rule(P, sums, h):
    tdir = M.orientation(P)
    return M.stripe_rule(P, sums, h, tdir=tdir)


def sim_frames(D):
    ld = lambda n: np.asarray(Image.open(D + '/' + n).convert('L'), dtype=np.float32)
    W, B = ld('white.png'), ld('black.png')
    pairs = [(ld('gray_%d.png' % k), ld('gray_%d_inv.png' % k)) for k in range(11)]
    sums = np.stack([p[0] + p[1] for p in pairs])
    ab = M.fit_pairs(sums.mean(0), sums.var(0, ddof=1), (W - B) >= 8)
    return M.prep(None, ab, W=W, B=B, pairs=pairs), sums, ab


def main(a):
    if a[0] == 'real':
        c, h = int(a[1]), int(a[2])
        F = M.load(c)
        P = M.prep(F, M.noisefit(F))
        col0, uc0 = M.decode(P)
        ref = M.plain(P)
        sums = np.stack([F[2 * k] + F[2 * k + 1] for k in range(20)])
        dd, ov, fit = rule(P, sums, h)
        col, uc = M.decode(P, d=dd, certain_override=ov)
        both = ~np.isnan(col) & ~np.isnan(ref)
        agree = (np.abs(col - ref) <= uc + 0.5)[both].mean()
        print('capture %d: defaults coverage %.4f outliers %d | h=%d coverage %.4f outliers %d agreement %.4f '
              '| tie-free plain outliers %d | averaged noise b %.4f' % (
                  c, M.coverage(col0, ref), M.outliers(col0), h, M.coverage(col, ref), M.outliers(col), agree,
                  M.outliers(ref), fit[1]))
    elif a[0] == 'sim':
        D, h = a[1], int(a[2])
        P, sums, ab = sim_frames(D)
        truth = np.asarray(Image.open(D + '/truth_col.tif'))
        lit = np.asarray(Image.open(D + '/lit.png')) > 0
        def rates(col):
            dec = ~np.isnan(col) & lit
            gross = dec & ~(np.abs(col - truth) <= 1)
            return 100 * dec.sum() / lit.sum(), 100 * gross.sum() / max(dec.sum(), 1)
        col0, _ = M.decode(P, ncols=1280)
        dd, ov, fit = rule(P, sums, h)
        col, _ = M.decode(P, d=dd, certain_override=ov, ncols=1280)
        added = ~np.isnan(col) & np.isnan(col0) & lit
        wrong = added & ~(np.abs(col - truth) <= 1)
        print('%s: defaults decoded %.3f gross %.3f | h=%d decoded %.3f gross %.3f | added %.3f %% of lit, '
              'wrong %.1f %% of added' % ((D,) + rates(col0) + (h,) + rates(col) + (
                  100 * added.sum() / lit.sum(), 100 * wrong.sum() / max(added.sum(), 1))))
    elif a[0] == 'gate':
        if a[1] == 'real':
            sets = []
            for c in range(5):
                F = M.load(c)
                sets.append(('capture_%d' % c, M.prep(F, M.noisefit(F))))
        else:
            sets = [(a[1], sim_frames(a[1])[0])]
        for name, P in sets:
            fine = P['d'][-1]
            unc = (np.abs(fine) <= P['thr']) & P['lit']
            nb = unc & (M.K * P['sig'] >= 0.1 * P['C'])
            print('%s: finest plane uncertain %.2f %% of lit, F_noise %.2f %% of lit' % (
                name, 100 * unc.sum() / P['lit'].sum(), 100 * nb.sum() / P['lit'].sum()))
    else:
        sys.exit(__doc__)


if __name__ == '__main__':
    main(sys.argv[1:] if len(sys.argv) > 1 else ['?'])
