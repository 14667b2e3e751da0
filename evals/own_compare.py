import sys, pandas as pd
a, b = (pd.read_csv(f"{x}/summary.csv").set_index("scene") for x in sys.argv[1:3])
cols = ["median", "p95", "max", "rms", "len", "base", "lost", "ok"]
d = a[cols].join(b[cols], rsuffix="_new")
rows = []
for s in d.index:
    r = d.loc[s]
    if any(abs(r[c] - r[c + "_new"]) > 2e-3 for c in ["median","p95","max","rms","len","base"]) or r.ok != r.ok_new or r.lost != r.lost_new:
        rows.append(s)
with pd.option_context("display.width", 250):
    print(d.loc[rows].round(3).to_string())
print(f"{int(a.ok.sum())}/{len(a)} -> {int(b.ok.sum())}/{len(b)}; lost {int(a.lost.sum())} -> {int(b.lost.sum())}")
