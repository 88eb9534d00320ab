"""Sorting networks for the few keys of a bucket (compiled into `fibres.slicing`'s topology
pass): fixed sequences of compare-exchanges, without the data-dependent branches of an
insertion sort (Knuth, The Art of Computer Programming vol. 3, §5.3.4). The networks are the
known optimal ones for 4 (5 comparators), 6 (12) and 8 (19) keys; with distinct keys any
sort gives the same order, so they replace the insertion sort exactly. (Tried for the
topology pass and no faster: a radix sort of the half-edges by larger then smaller vertex,
ranks by counting in each bucket, the pieces by union-find in the pairing loop, a
branch-free flood fill.)
"""
from __future__ import annotations

__all__ = []

#: the comparators (i, j), i < j, of the networks by number of keys
NETWORKS = {
    4: ((0, 1), (2, 3), (0, 2), (1, 3), (1, 2)),
    6: ((0, 5), (1, 3), (2, 4), (1, 2), (3, 4), (0, 3), (2, 5), (0, 1), (2, 3), (4, 5),
        (1, 2), (3, 4)),
    8: ((0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7), (0, 1), (2, 3),
        (4, 5), (6, 7), (2, 4), (3, 5), (1, 4), (3, 6), (1, 2), (3, 4), (5, 6)),
}


def _sort_small(key, s, m):  # pragma: no cover - compiled by numba (inlined)
    """Sort ``key[s:s + m]`` in place by the network of `NETWORKS` when m is 4, 6 or 8
    (written out: numba keeps the keys in registers) and return True; else False."""
    if m == 6:
        k0, k1, k2, k3, k4, k5 = key[s], key[s + 1], key[s + 2], key[s + 3], key[s + 4], \
            key[s + 5]
        k0, k5 = min(k0, k5), max(k0, k5)
        k1, k3 = min(k1, k3), max(k1, k3)
        k2, k4 = min(k2, k4), max(k2, k4)
        k1, k2 = min(k1, k2), max(k1, k2)
        k3, k4 = min(k3, k4), max(k3, k4)
        k0, k3 = min(k0, k3), max(k0, k3)
        k2, k5 = min(k2, k5), max(k2, k5)
        k0, k1 = min(k0, k1), max(k0, k1)
        k2, k3 = min(k2, k3), max(k2, k3)
        k4, k5 = min(k4, k5), max(k4, k5)
        k1, k2 = min(k1, k2), max(k1, k2)
        k3, k4 = min(k3, k4), max(k3, k4)
        key[s], key[s + 1], key[s + 2], key[s + 3], key[s + 4], key[s + 5] = \
            k0, k1, k2, k3, k4, k5
        return True
    if m == 4:
        k0, k1, k2, k3 = key[s], key[s + 1], key[s + 2], key[s + 3]
        k0, k1 = min(k0, k1), max(k0, k1)
        k2, k3 = min(k2, k3), max(k2, k3)
        k0, k2 = min(k0, k2), max(k0, k2)
        k1, k3 = min(k1, k3), max(k1, k3)
        k1, k2 = min(k1, k2), max(k1, k2)
        key[s], key[s + 1], key[s + 2], key[s + 3] = k0, k1, k2, k3
        return True
    if m == 8:
        k0, k1, k2, k3 = key[s], key[s + 1], key[s + 2], key[s + 3]
        k4, k5, k6, k7 = key[s + 4], key[s + 5], key[s + 6], key[s + 7]
        k0, k2 = min(k0, k2), max(k0, k2)
        k1, k3 = min(k1, k3), max(k1, k3)
        k4, k6 = min(k4, k6), max(k4, k6)
        k5, k7 = min(k5, k7), max(k5, k7)
        k0, k4 = min(k0, k4), max(k0, k4)
        k1, k5 = min(k1, k5), max(k1, k5)
        k2, k6 = min(k2, k6), max(k2, k6)
        k3, k7 = min(k3, k7), max(k3, k7)
        k0, k1 = min(k0, k1), max(k0, k1)
        k2, k3 = min(k2, k3), max(k2, k3)
        k4, k5 = min(k4, k5), max(k4, k5)
        k6, k7 = min(k6, k7), max(k6, k7)
        k2, k4 = min(k2, k4), max(k2, k4)
        k3, k5 = min(k3, k5), max(k3, k5)
        k1, k4 = min(k1, k4), max(k1, k4)
        k3, k6 = min(k3, k6), max(k3, k6)
        k1, k2 = min(k1, k2), max(k1, k2)
        k3, k4 = min(k3, k4), max(k3, k4)
        k5, k6 = min(k5, k6), max(k5, k6)
        key[s], key[s + 1], key[s + 2], key[s + 3] = k0, k1, k2, k3
        key[s + 4], key[s + 5], key[s + 6], key[s + 7] = k4, k5, k6, k7
        return True
    return False
