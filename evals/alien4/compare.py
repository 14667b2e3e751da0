"""Compare two score.py result folders: python compare.py A B (scenes whose figures differ)."""
import sys, pandas as pd
a, b = (pd.read_csv(f"{x}/summary.csv").set_index("scene") for x in sys.argv[1:3])
cols = ["lost", "med_angle", "p95_angle", "max_angle", "med_rms_px", "max_len_pct", "med_base_px", "pass"]
num = cols[1:-1]
rows = [s for s in a.index if s in b.index and (any(abs(a.loc[s, c] - b.loc[s, c]) > 2e-3 for c in num)
        or a.loc[s, "pass"] != b.loc[s, "pass"] or a.loc[s, "lost"] != b.loc[s, "lost"])]
d = pd.concat({"A": a.loc[rows, cols], "B": b.loc[rows, cols]}, axis=1).swaplevel(axis=1).sort_index(axis=1, level=0, sort_remaining=False)
d = d[[ (c, w) for c in cols for w in ("A", "B")]]
with pd.option_context("display.width", 250, "display.max_columns", 30):
    print(d.round(2).to_string())
print(f"{int(a['pass'].sum())}/{len(a)} -> {int(b['pass'].sum())}/{len(b)}; lost {int(a.lost.sum())} -> {int(b.lost.sum())}")
