#!/usr/bin/env python3
"""Compares the verdicts of two directories of diagnose JSON (examples/diagnose_golden's output,
or `diagnose --json` files): per file, each feature's name, flagged and significant, its suggested
term; the verification's edits (terms, verified, reason) and second round; and each edit's gain
to 1e-6 relative. Prints every difference and the largest relative gain difference; exit 1 if
a verdict differs.
   benches/verdicts.py BEFORE_DIR AFTER_DIR"""
import json, os, sys


def verdicts(d):
    feats = [(f["name"], f.get("flagged"), f.get("significant"), f.get("suggested_term"))
             for f in d.get("features", [])]
    v = d.get("verification") or {}
    def edits(v):
        return [(e["terms"], e["verified"]) for e in (v or {}).get("edits", [])]
    def gains(v):
        return [e["gain"] for e in (v or {}).get("edits", [])]
    sr = v.get("second_round") or {}
    comb = (sr.get("combined") or {}).get("terms")
    return (feats, edits(v), edits(sr), comb, v.get("not_run")), gains(v) + gains(sr)


def main(a, b):
    bad, worst, n = 0, 0.0, 0
    for name in sorted(os.listdir(a)):
        if not name.endswith(".json"):
            continue
        pb = os.path.join(b, name)
        if not os.path.exists(pb):
            print(f"{name}: missing in {b}"); bad += 1; continue
        (va, ga), (vb, gb) = (verdicts(json.load(open(os.path.join(x, name)))) for x in (a, b))
        n += 1
        if va != vb:
            bad += 1
            print(f"{name}: verdicts differ\n  before {va}\n  after  {vb}")
            continue
        for x, y in zip(ga, gb):
            rel = abs(x - y) / max(abs(x), 1e-300)
            worst = max(worst, rel)
            if rel > 1e-6:
                bad += 1
                print(f"{name}: gain {x} -> {y} ({rel:.1e} relative)")
    print(f"{n} files, {bad} differences, largest relative gain difference {worst:.1e}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
