#!/usr/bin/python3
"""Paper estimate of the discharge phases of the sheet rig's upper chamber (docs/verification.md,
"A chamber whose flow tails off") for chambers of a given length, flat floor, slot outlet.

usage: tools/sheet_chamber_estimate.py [--lengths 0.30,0.40,0.45,0.50,0.55,0.60,0.70]
                                       [--repose 22,26] [--rate 1.0] [--head 0.04]

Quasi-two-dimensional: a bed of M = 6 kg at the bulk density 743 kg/m^3 in a chamber of
length L and width 0.10 m (depth H = M / (rho_b w L)), the 40 mm slot in its middle, spanning
the width. While the crater of the free surface stays more than --head (about one outlet
width) above the outlet the flow keeps Beverloo's rate Q (--rate: 1.0 kg/s measured for the
5-7 mm grains, cases/sheet_coarse.toml); the mass crossed by time t is then about Q t (the
initial bulk's excess makes up for the flaps' opening). With crater flanks at the angle of
repose theta rising from the outlet's edges, the crater's bottom reaches --head above the
outlet when the grain above min(H, head + x tan theta) has left (x from an outlet edge): that
mass over Q is when the reduction starts. What can never leave lies in two wedges at theta
beside the outlet (min(H, x tan theta)); what lies between them and the crater at --head
feeds the tail by avalanches on the flanks, at a rate falling from Q to 0: about twice its mass
over Q. Prints a table; checks itself against the measured 0.30 m chamber (reduction from
4.74 s, 4.97 kg crossed by 5 s).
"""

import argparse
import math

RHO_B, WIDTH, OUTLET, MASS = 743.0, 0.10, 0.04, 6.0


def integrate(f, a, n=4000):
    h = a / n
    return h * (0.5 * f(0.0) + sum(f(k * h) for k in range(1, n)) + 0.5 * f(a))


def estimate(length, repose_deg, rate, head):
    a = (length - OUTLET) / 2  # floor beside one outlet edge
    t = math.tan(math.radians(repose_deg))
    depth = MASS / (RHO_B * WIDTH * length)
    left = RHO_B * WIDTH * 2 * integrate(lambda x: min(depth, x * t), a)
    out_at_reduction = RHO_B * WIDTH * (
        OUTLET * (depth - head) + 2 * integrate(lambda x: depth - min(depth, head + x * t), a))
    tail = MASS - left - out_at_reduction
    return {"depth": depth, "left": left, "reduction": out_at_reduction / rate,
            "out_at_reduction": out_at_reduction, "tail": tail,
            "end": out_at_reduction / rate + 2 * tail / rate}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--lengths", default="0.30,0.40,0.45,0.50,0.55,0.60,0.70")
    p.add_argument("--repose", default="22,26")
    p.add_argument("--rate", type=float, default=1.0)
    p.add_argument("--head", type=float, default=0.04)
    a = p.parse_args()
    print("| chamber (m) | bed depth (m) | repose | reduction from (s) | out then (kg) | "
          "tail (kg) | flow ends (s) | left (kg) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for length in (float(x) for x in a.lengths.split(",")):
        for th in (float(x) for x in a.repose.split(",")):
            e = estimate(length, th, a.rate, a.head)
            print(f"| {length:.2f} x 0.10 | {e['depth']:.3f} | {th:g} deg | {e['reduction']:.1f} | "
                  f"{e['out_at_reduction']:.2f} | {e['tail']:.2f} | {e['end']:.1f} | "
                  f"{e['left']:.2f} ({100 * e['left'] / MASS:.0f} %) |")


if __name__ == "__main__":
    main()
