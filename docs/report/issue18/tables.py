#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Issue 18 report tables from `procam bench` results (docs/report/issue18/README.md).

usage: tables.py TITLE BENCH.json KEEP_DIR [TITLE BENCH.json KEEP_DIR]...

BENCH.json: `procam bench --out DIR` (DIR/bench.json); KEEP_DIR: its `--keep DIR`,
whose <scene>/<method>/outputs.json report gives the per-step rows (ensemble, auto).
Prints, per set, the acceptance table, the per-step table (predicted gain, probe
verdicts, measured change, acceptance) and the gross errors per vote class.
Gross = % of decoded lit pixels with |column error| > 1 (gross_error_fraction).
"""
import json
import os
import sys


def find(x, key):
    if isinstance(x, dict):
        for k, v in x.items():
            if k == key and isinstance(v, list):
                return v
            f = find(v, key)
            if f is not None:
                return f
    elif isinstance(x, list):
        for v in x:
            f = find(v, key)
            if f is not None:
                return f
    return None


def load(bench, keep):
    runs = {}
    for r in json.load(open(bench))['runs']:
        if r.get('ok'):
            runs.setdefault(r['scene'], {})[r['method']] = r
    steps = {}
    for sc in runs:
        for m in ('ensemble', 'auto'):
            p = os.path.join(keep, sc, m, 'outputs.json')
            if os.path.exists(p):
                steps[(sc, m)] = find(json.load(open(p)), 'steps') or []
    return runs, steps


def g(r):
    return 100 * r['evaluation']['gross_error_fraction']


def cell(r):
    return '%.3f %% (%d pat., %.1f %% dec.)' % (g(r), r['patterns'], 100 * r['evaluation']['decoded_fraction'])


def main_table(runs, out):
    out.append('| scene | best method (gross %) | ensemble-nocorr | ensemble (rounds) | auto | rounds and auto ≤ nocorr? | auto ≤ ensemble patterns, within 0.02 pp of best? |')
    out.append('|---|---|---|---|---|---|---|')
    n = [0, 0, 0, 0, 0]  # scenes, pay (0.01 pp tolerance), patterns, near best, pay strictly
    for sc in sorted(runs):
        R = runs[sc]
        best = min(R, key=lambda m: (g(R[m]), m))
        nc, en, au = R['ensemble-nocorr'], R['ensemble'], R['auto']
        pay = g(en) <= g(nc) + 0.01 and g(au) <= g(nc) + 0.01
        strict = g(en) <= g(nc) and g(au) <= g(nc)
        pat = au['patterns'] <= en['patterns']
        near = g(au) <= g(R[best]) + 0.02
        for i, v in enumerate((1, pay, pat, near, strict)):
            n[i] += v
        nr = 'yes' if near else 'NO (+%.3f pp)' % (g(au) - g(R[best]))
        payc = 'yes' if pay else 'NO (ens %+.3f, auto %+.3f pp)' % (g(en) - g(nc), g(au) - g(nc))
        out.append('| %s | %s %.3f | %s | %s | %s | %s | %s, %s |' % (
            sc, best, g(R[best]), cell(nc), cell(en), cell(au), payc, 'yes' if pat else 'NO', nr))
    return n


def step_table(runs, steps, out):
    out.append('| scene | method | step | predicted gain (% of lit) | probe: fixable / too dark / flagged | taken | measured change of flagged (pp) | acceptance | discarded |')
    out.append('|---|---|---|---:|---:|---|---:|---:|---|')
    for sc in sorted(runs):
        for m in ('ensemble', 'auto'):
            for s in steps.get((sc, m), []):
                t = s.get('taken')
                p = s.get('probe')
                pc = '%d / %d / %d' % (p['fixable'], p.get('too_dark_under_mask', 0), p['flagged']) if p else '–'
                mc = '%.3f' % (100 * s['measured_change']) if t and 'measured_change' in s else '–'
                ac = '%.2f' % s['acceptance'] if t and 'acceptance' in s else '–'
                di = ('yes' if s.get('discarded') else 'no') if t and 'acceptance' in s else '–'
                out.append('| %s | %s | %s | %.3f | %s | %s | %s | %s | %s |' % (
                    sc, m, s['step'], 100 * s['predicted_gain'], pc, 'yes' if t else 'no', mc, ac, di))


def classes(runs, out):
    out.append('| scene | method | partial: decoded / gross | subsurface: decoded / gross | all-agree gross | inter-refl. gross |')
    out.append('|---|---|---:|---:|---:|---:|')
    for sc in sorted(runs):
        for m in ('ensemble-nocorr', 'auto'):
            c = runs[sc][m]['evaluation'].get('gross_by_class', {})
            if c:
                out.append('| %s | %s | %d / %d | %d / %d | %d | %d |' % (
                    sc, m, c['partial']['decoded'], c['partial']['gross'], c['subsurface']['decoded'],
                    c['subsurface']['gross'], c['all_agree']['gross'], c['interreflection']['gross']))


def main(argv):
    if len(argv) < 3 or len(argv) % 3:
        sys.exit(__doc__)
    out = []
    for name, bench, keep in zip(argv[0::3], argv[1::3], argv[2::3]):
        runs, steps = load(bench, keep)
        out += ['### ' + name, '']
        n = main_table(runs, out)
        out += ['', 'Met: rounds/auto ≤ nocorr on %d of %d scenes (strictly: %d); auto ≤ ensemble patterns on %d; '
                'auto within 0.02 pp of best on %d.' % (n[1], n[0], n[4], n[2], n[3]), '']
        step_table(runs, steps, out)
        out.append('')
        classes(runs, out)
        out.append('')
    print('\n'.join(out))


if __name__ == '__main__':
    main(sys.argv[1:])
