"""The arrays of two ``benchmarks/bits_record.py`` files compared bit for bit (NaN equal to NaN):
prints each array that differs and how many do."""

import sys

import numpy as np

a, b = np.load(sys.argv[1]), np.load(sys.argv[2])
ka, kb = set(a.files), set(b.files)
print("only in base:", sorted(ka - kb)[:20])
print("only in new:", sorted(kb - ka)[:20])
bad = 0
for k in sorted(ka & kb):
    x, y = a[k], b[k]
    if x.shape != y.shape:
        print("SHAPE", k, x.shape, y.shape)
        bad += 1
        continue
    if not np.array_equal(x, y, equal_nan=True):
        d = np.nanmax(np.abs(x - y)) if x.size else 0
        print("DIFF", k, d, np.nanmax(np.abs(x)) if x.size else 0)
        bad += 1
print(bad, "differ of", len(ka & kb))
