#!/usr/bin/python3
"""Scores a map's labels against a held-out long-run truth (issue 38).

    bench/labels/score_map.py TRUTH.csv MAP.h5 [--json]

TRUTH.csv comes from bench/labels/make_truth.sh (bench/truth_labels.cc): per sampled grid point the labels of
τ 10,000–20,000 (suffix _a) and τ 20,000–30,000 (suffix _b). MAP.h5 is the map file of `bistable run` on the
same grid (axes alpha x omega; a grid point index is i_alpha * n_omega + i_omega).

Truth class (window b): chaotic when motion_b is chaotic (LLE > 0.01 over 10,000 τ); quasi-periodic/marginal
when not chaotic, no period and |LLE| <= 0.003; otherwise intrawell/interwell. The truth has settled at a point
when both windows give the same motion and period. Map classes: motion 0 intrawell, 1 interwell, 2 chaotic,
3 quasi-periodic (settled mode), 4 unresolved (settled mode); a label is confident unless it is unresolved.

Figures (over the points whose truth settled):
  agree3   share of confident map labels whose motion (intrawell/interwell/chaotic; a quasi-periodic label
           counts as its well, from y_min/y_max) equals the truth's
  agree4   the same with the quasi-periodic class told apart (truth and map)
  chaotic precision / recall, chaotic area (map share of all points vs the truth's share)
  unresolved share (all points), and by Omega band
  period   among confident non-chaotic map labels with period >= 1, the share whose period equals the truth's
  hd_p1    among truly period-1 points, the share whose map hd_index < 1e-3
"""
import csv
import json
import sys

import h5py
import numpy as np

QUASI_LLE = 0.003
INTRA, INTER, CHAOS, QUASI, UNRES = 0, 1, 2, 3, 4


def load_truth(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    t = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    t["index"] = t["index"].astype(int)
    return t


def truth_class(motion, period, lle):
    c = motion.astype(int).copy()
    quasi = (c != CHAOS) & (period == 0) & (np.abs(lle) <= QUASI_LLE)
    c[quasi] = QUASI
    return c


def well_of(ymin, ymax):
    return np.where((ymin > 0) | (ymax < 0), INTRA, INTER)


def main():
    truth_path, map_path = sys.argv[1], sys.argv[2]
    as_json = "--json" in sys.argv
    t = load_truth(truth_path)
    with h5py.File(map_path, "r") as f:
        n_om = f["omega"].shape[0]
        ia, io = t["index"] // n_om, t["index"] % n_om
        get = lambda k: np.asarray(f[k][()])[ia, io] if k in f else None
        alpha_ok = np.allclose(np.asarray(f["alpha"][()])[ia], t["alpha"], rtol=1e-12)
        omega_ok = np.allclose(np.asarray(f["omega"][()])[io], t["omega"], rtol=1e-12)
        if not (alpha_ok and omega_ok):
            sys.exit("the map's grid is not the truth's")
        motion = get("motion").astype(int)
        period = get("period")
        hd = get("hd_index")
        ymin, ymax = get("y_min"), get("y_max")
        settle = get("settle_time")
    t_cls3 = t["motion_b"].astype(int)
    t_cls4 = truth_class(t["motion_b"], t["period_b"], t["lle_b"])
    settled = (t["motion_a"] == t["motion_b"]) & (t["period_a"] == t["period_b"])
    conf = motion != UNRES
    m3 = np.where(motion == QUASI, well_of(ymin, ymax), motion)
    m4 = motion.copy()
    # The paper's mode has no quasi-periodic class: compare it as 3 classes only.
    s = settled
    out = {"points": int(len(motion)), "truth_settled": int(s.sum()),
           "truth_chaotic": int((t_cls3[s] == CHAOS).sum())}
    sel = s & conf
    out["confident"] = int(sel.sum())
    out["agree3"] = float((m3[sel] == t_cls3[sel]).mean())
    out["agree4"] = float((m4[sel] == t_cls4[sel]).mean())
    mc, tc = (motion == CHAOS), (t_cls3 == CHAOS)
    out["chaotic_precision"] = float((mc & tc & s).sum() / max((mc & s).sum(), 1))
    out["chaotic_recall"] = float((mc & tc & s).sum() / max((tc & s).sum(), 1))
    out["chaotic_area_map"] = float(mc.mean())
    out["chaotic_area_truth"] = float(tc.mean())
    out["chaotic_area_map_on_settled"] = float(mc[s].mean())
    out["chaotic_area_truth_on_settled"] = float(tc[s].mean())
    out["unresolved"] = float((motion == UNRES).mean())
    bands = [(0, 0.5), (0.5, 1.0), (1.0, 1.5), (1.5, 2.0), (2.0, 2.5), (2.5, 3.01)]
    out["unresolved_by_omega"] = {f"{a}-{b}": float((motion[(t['omega'] >= a) & (t['omega'] < b)] == UNRES).mean())
                                  for a, b in bands}
    out["quasi_map"] = float((motion == QUASI).mean())
    out["quasi_truth"] = float((t_cls4[s] == QUASI).mean())
    pm = sel & (motion != CHAOS) & (period >= 1)
    out["period_claims"] = int(pm.sum())
    out["period_right"] = float((period[pm] == t["period_b"][pm]).mean()) if pm.any() else float("nan")
    nonch = sel & (motion != CHAOS)
    out["period0_share_map"] = float((period[nonch] == 0).mean())
    tnon = s & (t_cls3 != CHAOS)
    out["period0_share_truth"] = float((t["period_b"][tnon] == 0).mean())
    p1 = s & (t["period_b"] == 1) & (t_cls3 != CHAOS)
    out["hd_p1_below_1e-3"] = float((hd[p1] < 1e-3).mean())
    if settle is not None:
        st = settle[np.isfinite(settle)]
        out["settle_time_median"] = float(np.median(st)) if st.size else float("nan")
        out["settle_time_p90"] = float(np.percentile(st, 90)) if st.size else float("nan")
        out["settle_time_mean"] = float(st.mean()) if st.size else float("nan")
    # Disagreements by kind (map -> truth), for the report.
    names = ["intra", "inter", "chaos", "quasi", "unres"]
    conf_pairs = {}
    for a, b in zip(m4[sel], t_cls4[sel]):
        if a != b:
            k = f"{names[a]}->{names[b]}"
            conf_pairs[k] = conf_pairs.get(k, 0) + 1
    out["disagreements4"] = dict(sorted(conf_pairs.items(), key=lambda kv: -kv[1]))
    if as_json:
        print(json.dumps(out, indent=1))
    else:
        for k, v in out.items():
            print(f"{k:32s} {v:.4f}" if isinstance(v, float) else f"{k:32s} {v}")


if __name__ == "__main__":
    main()
