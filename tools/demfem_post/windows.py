"""Statistics of a series over a time window, in pure Python (the reports' key figures:
the same sums in the same order as the reports have always made, so their numbers keep
their last bits)."""

import math


def window(t, v, lo, hi):
    """The values of `v` whose times `t` lie in [lo, hi]."""
    return [x for s, x in zip(t, v) if lo <= s <= hi]


def stats(values):
    """Mean, population standard deviation, min, max and count of `values` (None if empty)."""
    if not values:
        return None
    m = sum(values) / len(values)
    sd = math.sqrt(sum((x - m) ** 2 for x in values) / len(values))
    return {"mean": m, "std": sd, "min": min(values), "max": max(values), "samples": len(values)}


def moving_average(t, v, width):
    """Centred moving average over `width` seconds (uniform samples assumed)."""
    if len(t) < 2 or width <= 0:
        return list(v)
    dt = (t[-1] - t[0]) / (len(t) - 1)
    half = max(1, int(round(width / dt / 2)))
    prefix = [0.0]
    for x in v:
        prefix.append(prefix[-1] + x)
    out = []
    for i in range(len(v)):
        a, b = max(0, i - half), min(len(v), i + half + 1)
        out.append((prefix[b] - prefix[a]) / (b - a))
    return out
