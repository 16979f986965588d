#!/usr/bin/env python3
"""Builds a gap-bench corpus directory (docs/gap.md "Bench"):

  make_corpus.py gen2 --seeds 1000-1019 --out DIR [--short]
  make_corpus.py gfd  --seeds 1000-1009 --out DIR --gfd ../shared/data/gfd --ptda build/release/cli/ptda

Each case goes to DIR/<family>-<seed>/ (rec/, nominal.toml, truth.json); DIR/corpus.json lists them.
Development seeds are 1000-1999 (docs/gap.md "Seeds"); evaluation seeds are chosen by the lead.
"""

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import g2common as C  # noqa: E402


def seed_list(text):
    out = []
    for part in text.split(","):
        if "-" in part:
            a, b = part.split("-")
            out.extend(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("family", choices=["gen2", "gfd"])
    ap.add_argument("--seeds", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--kinds", default="", help="gen2: comma-separated slots to force, in turn")
    ap.add_argument("--short", action="store_true", help="gen2: 2 program cycles only (smoke test)")
    ap.add_argument("--gfd", default="", help="gfd: directory of the GFD CSV files")
    ap.add_argument("--ptda", default="ptda", help="gfd: the ptda executable (for `ptda import`)")
    ap.add_argument("--append", action="store_true", help="keep cases already listed in corpus.json")
    a = ap.parse_args()
    seeds = seed_list(a.seeds)
    os.makedirs(a.out, exist_ok=True)
    kinds = [k for k in a.kinds.split(",") if k]
    cases = []
    manifest = os.path.join(a.out, "corpus.json")
    if a.append and os.path.exists(manifest):
        import json
        with open(manifest) as f:
            cases = json.load(f)["cases"]
    for i, s in enumerate(seeds):
        name = f"{a.family}-{s}"
        d = os.path.join(a.out, name)
        t0 = time.time()
        if a.family == "gen2":
            import g2robot
            info = g2robot.make_case(s, d, kind=kinds[i % len(kinds)] if kinds else None, short_s=a.short)
        else:
            import g2gfd
            if not a.gfd:
                ap.error("gfd needs --gfd DIR")
            info = g2gfd.make_case(s, d, a.gfd, a.ptda)
        cases = [c for c in cases if c["name"] != name]
        cases.append({"name": name, "recording": f"{name}/rec", "nominal": f"{name}/nominal.toml",
                      "truth": f"{name}/truth.json"})
        print(f"{name}: {info['category']}: {info['description']} ({time.time() - t0:.1f} s)", flush=True)
    C.write_manifest(a.out, "gen2" if a.family == "gen2" else "gfd-injected", cases)


if __name__ == "__main__":
    main()
