#!/usr/bin/python3
"""Prints the kPinned rows of tests/golden/gfd_test.cpp from a finished run of that test: its scratch
directory (gfd_<pid> under the golden scratch root) holds, per load and channel, the monitor JSONL and
`ptda evaluate` JSON of each method. The 2U values are counted by brute force over all pairs, as the
test does. Usage: scripts/gfd_pins.py SCRATCH/gfd_<pid>
"""
import json, sys, os
d = sys.argv[1]
def rows(p):
    return [json.loads(l) for l in open(p) if l.strip()]
def twice_u(h, f):
    return sum(2 if x > y else (1 if x == y else 0) for x in f for y in h)
def feat(rs, k):
    return [r[k] for r in rs if r['status'] == 'scored']
for load in (0, 20, 40, 60, 80):
    for ch in ('a1', 'a2', 'a3', 'a4'):
        for m in ('raw', 'tda', 'ptda'):
            c = f'{d}/{load}_{ch}'
            e = json.load(open(f'{c}/eval.{m}.json'))
            h = rows(f'{c}/h.{m}.jsonl'); b = rows(f'{c}/b.{m}.jsonl')
            ru = twice_u(feat(h, 'rms_res'), feat(b, 'rms_res')); eu = twice_u(feat(h, 'entropy_res'), feat(b, 'entropy_res'))
            print(f'    {{{load}, "{ch}", "{m}", {e["healthy"]["scored"]}, {e["faulty"]["scored"]}, {e["rms_res"]["ratio"]:.9g}, {ru}, '
                  f'{e["entropy_res"]["ratio"]:.9g}, {eu}, {"true" if e["healthy"]["alarm"] else "false"}, {"true" if e["faulty"]["alarm"] else "false"}}},')
