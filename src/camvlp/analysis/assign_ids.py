"""IDs for a site of more fixtures than a frame has IDs: every view told apart by geometry.

:func:`assign_ids` chooses IDs that leave as few of a site's views ambiguous
(:func:`~camvlp.analysis.study.site_views.ambiguous_views`) as it can find: first a greedy
colouring in which lights seen together get different IDs and no light is seen beside its
readout-reversal partner (an ID whose frame read backwards is another ID's: a photo whose
readout direction is not known could read one as the other), then a local search that gives
each light of a view not yet told apart the ID that tells the most views apart, a view being
told apart by a triangle of its lights that no other three fixtures of the site repeat.
:func:`assignment_report` measures the result against a random assignment on poses drawn
anew.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.analysis.study.common import Progress
from camvlp.analysis.study.site_views import (
    SiteGeometry,
    Views,
    ambiguous_views,
    identified_share,
    seen_together,
)

__all__ = ["Assignment", "assign_ids", "assignment_report"]


#: Costs of the greedy colouring, per light seen together with the one being given an ID:
#: one of the same ID, one of its readout-reversal partner; and per use of the ID so far
#: (the IDs used about equally often).
_SAME, _REVERSED, _USED = 1.0, 4.0, 1e-3

#: The search's cost, in views left ambiguous, of a light seen together with one of the same
#: ID (a view of both reads that ID twice and keeps one of them; two lights of one ID tell no
#: place with gravity) or of its readout-reversal partner (read the wrong way, each is the
#: other): dearer than the views the search weighs, so it gives up few of them.
_CLASH = 20.0


def _greedy(neighbours: list[np.ndarray], reverse: np.ndarray, rng: np.random.Generator):
    """IDs (N,) in a random order, each the one least seen together with its neighbours
    (the same ID, or its readout-reversal partner, costing :data:`_SAME`, :data:`_REVERSED`)."""
    n_ids = reverse.size
    ids = np.full(len(neighbours), -1, dtype=np.int64)
    used = np.zeros(n_ids)
    for f in rng.permutation(len(neighbours)):
        there = ids[neighbours[f]]
        there = there[there >= 0]
        cost = _SAME * np.bincount(there, minlength=n_ids) + _USED * used
        partners = reverse[there]
        np.add.at(cost, partners[partners >= 0], _REVERSED)
        ids[f] = int(np.argmin(cost + 1e-6 * rng.random(n_ids)))
        used[ids[f]] += 1
    return ids


class _Triangles:
    """Every three lights some view sees together, each keyed by its shape and IDs up to a
    turn: two triangles of one key are one arrangement of the same IDs in two places.

    A view of three or more lights is told apart when one of its triangles is the only one
    of its key (sufficient, not necessary: :func:`ambiguous_views` is the exact test); the
    search makes keys unique by keeping down ``sum over keys of C(count, 2)``.
    """

    def __init__(self, views: Views, site: SiteGeometry, n: int, n_ids: int, tol_m: float):
        self.n_ids = n_ids
        t = _close_triples(site, _widest(views, site) + tol_m)
        p = site.flat[t]  # (T, 3, 2)
        u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        cross = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
        t[cross < 0] = t[cross < 0][:, [0, 2, 1]]  # counter-clockwise, seen from above
        p = site.flat[t]
        edge = np.rint(np.hypot(*(np.roll(p, -1, axis=1) - p).transpose(2, 0, 1)) / tol_m)
        # three lights on a line (twice the area under a tolerance's width along the longest
        # side) are the same turned half round with their order reversed: both orders
        line = np.abs(cross) <= 2.0 * tol_m * edge.max(axis=1) * tol_m
        self.orders = [t, np.where(line[:, None], t[:, ::-1], t)]
        shapes = []
        for tt in self.orders:
            q = site.flat[tt]
            e = np.rint(np.hypot(*(np.roll(q, -1, axis=1) - q).transpose(2, 0, 1)) / tol_m)
            # the edges from each vertex on, for each of the three turns of the vertices
            shapes.append(np.stack([np.roll(e, -r, axis=1) for r in range(3)], axis=1))
        both = np.concatenate(shapes, axis=1)  # (T, 6, 3)
        _, code = np.unique(both.reshape(-1, 3), axis=0, return_inverse=True)
        self.tri, self.shape = t, code.reshape(-1, 6).astype(np.int64)
        self.through = _through(t, n)

    def keys(self, which: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """Keys (K,) of triangles ``which`` (indices) under ``ids`` (N,): the least over the
        three turns of (shape, IDs in turn)."""
        m = self.n_ids
        turned = []
        for tt in self.orders:
            i = ids[tt[which]]  # (K, 3)
            turned.append(np.stack([np.roll(i, -r, axis=1) for r in range(3)], axis=1))
        t = np.concatenate(turned, axis=1)  # (K, 6, 3)
        code = (t[..., 0] * m + t[..., 1]) * m + t[..., 2]
        return np.min(self.shape[which] * m**3 + code, axis=1)


def _widest(views: Views, site: SiteGeometry) -> float:
    """The largest distance (metres, seen from above) between two lights a view sees."""
    widest = 0.0
    for s in views.seen:
        if s.size >= 2:
            xy = site.flat[s]
            widest = max(widest, float(np.max(np.hypot(*(xy[:, None] - xy[None]).T))))
    return widest


def _close_triples(site: SiteGeometry, reach: float) -> np.ndarray:
    """Every three fixtures (T, 3), indices ascending, each two within ``reach`` (metres,
    seen from above): whatever a camera could see together, wherever it stands (another
    placement of a view's lights may lie where no pose drawn looked)."""
    n = site.flat.shape[0]
    pairs = site.tree.query_pairs(reach, output_type="ndarray")
    if not pairs.size:
        return np.zeros((0, 3), dtype=np.intp)
    pairs = np.sort(pairs, axis=1)
    both = np.concatenate([pairs, pairs[:, ::-1]])
    both = both[np.lexsort((both[:, 1], both[:, 0]))]
    cut = np.searchsorted(both[:, 0], np.arange(n + 1))
    nb = [both[cut[f] : cut[f + 1], 1] for f in range(n)]
    out = []
    for a, b in pairs:  # a < b: the third after b, a neighbour of both
        c = np.intersect1d(nb[a], nb[b], assume_unique=True)
        c = c[c > b]
        if c.size:
            out.append(np.column_stack([np.full(c.size, a), np.full(c.size, b), c]))
    return np.concatenate(out) if out else np.zeros((0, 3), dtype=np.intp)


def _through(groups: np.ndarray, n: int) -> list[np.ndarray]:
    """Per fixture (``n``), the rows of ``groups`` (G, k) that hold it."""
    rows = np.repeat(np.arange(groups.shape[0]), groups.shape[1])
    order = np.argsort(groups.ravel(), kind="stable")
    cut = np.searchsorted(groups.ravel()[order], np.arange(n + 1))
    return [rows[order[cut[f] : cut[f + 1]]] for f in range(n)]


class _Search:
    """The views a set of IDs tells apart by a triangle of theirs that no other three
    fixtures repeat (:class:`_Triangles`), kept up to date as one fixture's ID changes.

    A view of three lights needs one such triangle; a view of four or more (with
    ``one_missing``) one among each three or more of its lights left with one missing.
    """

    def __init__(
        self, tri: _Triangles, views: Views, ids: np.ndarray, one_missing: bool, weights=None
    ):
        self.tri, self.ids = tri, ids
        self.keys = tri.keys(np.arange(tri.tri.shape[0]), ids)
        k, c = np.unique(self.keys, return_counts=True)
        self.counts = dict(zip(k.tolist(), c.tolist(), strict=True))
        index = {tuple(sorted(t)): i for i, t in enumerate(tri.tri.tolist())}
        units, owner = [], []
        for v, members in enumerate(views.seen):
            if members.size < 3:
                continue
            parts = [members]
            if one_missing and members.size >= 4:
                parts = [np.delete(members, m) for m in range(members.size)]
            for part in parts:
                trip = np.array(list(_triples(np.sort(part))), dtype=np.intp)
                units.append(np.array([index[tuple(t)] for t in trip.tolist()]))
                owner.append(v)
        self.owner = np.array(owner, dtype=np.intp)  # units in the order of their views
        lengths = np.array([u.size for u in units], dtype=np.intp)
        self.flat = np.concatenate(units) if units else np.zeros(0, np.intp)
        self.unit_start = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.intp)
        self.has_units, self.view_start = np.unique(self.owner, return_index=True)
        watched = np.zeros(tri.tri.shape[0], dtype=bool)
        watched[self.flat] = True
        self.watched = watched
        self.by_key: dict[int, set[int]] = {}
        for t in np.flatnonzero(watched).tolist():
            self.by_key.setdefault(int(self.keys[t]), set()).add(t)
        self.unique = np.array([self.counts[k] == 1 for k in self.keys.tolist()], dtype=bool)
        self.view_told = np.ones(len(views.seen), dtype=bool)
        self._tell()
        # each distinct set of lights once, weighed by the poses that see it
        self.weight = np.where(views.counts() >= 3, 1.0, 0.0) if weights is None else weights

    def _tell(self) -> None:
        """Which views are told apart, from which triangles' keys are unique."""
        if not self.flat.size:
            return
        unit_told = np.logical_or.reduceat(self.unique[self.flat], self.unit_start)
        self.view_told[self.has_units] = np.logical_and.reduceat(unit_told, self.view_start)

    def untold(self) -> float:
        """Views of three or more lights not told apart (weighed)."""
        return float(np.sum(self.weight[~self.view_told]))

    def relabel(self, f: int, new_id: int) -> None:
        """Give fixture ``f`` ID ``new_id``, and update which views are told apart."""
        mine = self.tri.through[f]
        old = self.keys[mine]
        self.ids[f] = new_id
        new = self.tri.keys(mine, self.ids)
        keys = set(old.tolist()) | set(new.tolist())
        before = {k: self.counts.get(k, 0) == 1 for k in keys}
        for t, a, b in zip(mine.tolist(), old.tolist(), new.tolist(), strict=True):
            self.counts[a] -= 1
            self.counts[b] = self.counts.get(b, 0) + 1
            if a != b and self.watched[t]:
                self.by_key[a].discard(t)
                self.by_key.setdefault(b, set()).add(t)
        self.keys[mine] = new
        for k in keys:  # the triangles whose key became, or stopped being, unique
            now = self.counts.get(k, 0) == 1
            if before[k] != now:
                for t in self.by_key.get(k, ()):
                    self.unique[t] = now
        self.unique[mine] = [self.counts[k] == 1 for k in new.tolist()]
        self._tell()


def _distinct(views: Views) -> tuple[Views, np.ndarray]:
    """The distinct sets of three or more lights of ``views`` (as a :class:`Views` without
    poses) and how many poses see each, shape (D,)."""
    sets: dict[tuple, int] = {}
    for members in views.seen:
        if members.size >= 3:
            key = tuple(members.tolist())
            sets[key] = sets.get(key, 0) + 1
    seen = [np.array(k, dtype=np.intp) for k in sets]
    empty = np.zeros((0, 3))
    return Views(empty, np.zeros((0, 3, 3)), seen), np.array(list(sets.values()), dtype=float)


def _triples(members: np.ndarray):
    """Every three of ``members`` (in their order)."""
    n = members.size
    for a in range(n):
        for b in range(a + 1, n):
            for c in range(b + 1, n):
                yield members[a], members[b], members[c]


def assign_ids(
    positions_m: np.ndarray,
    up: np.ndarray,
    reverse: np.ndarray,
    views: Views,
    *,
    rng: np.random.Generator,
    tol_m: float = 0.05,
    one_missing: bool = True,
    sweeps: int = 10,
    progress: Progress | None = None,
) -> np.ndarray:
    """IDs for the fixtures that tell apart as many of ``views`` as the search finds.

    A greedy colouring first (:func:`_greedy`); then, in up to ``sweeps`` sweeps over the
    lights of the views not yet told apart (:class:`_Search`), each light is given the ID
    that tells the most views apart, readout-reversal partners and lights of one ID seen
    together costing :data:`_CLASH` views each.

    Parameters
    ----------
    positions_m : ndarray, shape (N, 3)
        Fixture centres, metres.
    up : ndarray, shape (3,)
        The map's up.
    reverse : ndarray of int, shape (n_ids,)
        Each ID's readout-reversal partner, -1 for none
        (:attr:`~camvlp.model.linecode.FrameFormat.reversed_ids`).
    views : Views
        The views to tell apart.
    rng : numpy.random.Generator
        The search's source of randomness.
    tol_m : float
        Triangles whose sides agree within this (metres) are one shape.
    one_missing : bool
        As for :func:`ambiguous_views`.
    sweeps : int
        Sweeps of the search, at most (it stops when one changes nothing).
    progress : callable, optional
        Called with (sweeps done, ``sweeps``).

    Returns
    -------
    ndarray of int, shape (N,)
    """
    n, n_ids = len(positions_m), reverse.size
    together = seen_together(views, n)
    ids = _greedy(together, reverse, rng)
    site = SiteGeometry(positions_m, up, ids, n_ids)
    distinct, weights = _distinct(views)
    search = _Search(_Triangles(views, site, n, n_ids, tol_m), distinct, ids, one_missing, weights)

    def cost(f: int) -> float:
        near = ids[together[f]]
        clash = int(np.sum(near == ids[f])) + int(np.sum(reverse[near] == ids[f]))
        return search.untold() + _CLASH * clash

    for sweep in range(int(sweeps)):
        untold = np.flatnonzero((search.weight > 0) & ~search.view_told)
        # the lights of the views not told apart, and those that clash with one seen with them
        todo = [
            f
            for f in range(n)
            if np.any(ids[together[f]] == ids[f]) or np.any(reverse[ids[together[f]]] == ids[f])
        ]
        todo = np.unique(
            np.concatenate([np.asarray(todo, dtype=np.int64)] + [distinct.seen[v] for v in untold])
        )
        changed = 0
        for f in rng.permutation(todo).tolist():
            old = int(ids[f])
            best, best_id = cost(f), old
            for cand in rng.permutation(n_ids).tolist():
                if cand == old:
                    continue
                search.relabel(f, cand)
                c = cost(f)
                if c < best:
                    best, best_id = c, cand
            search.relabel(f, best_id)
            changed += best_id != old
        if progress is not None:
            progress(sweep + 1, int(sweeps))
        if not changed:
            break
    return ids.copy()


@dataclass(frozen=True)
class Assignment:
    """IDs assigned to a site and how well they tell its views apart
    (:func:`assignment_report`), against a random assignment, on poses the search did not
    see.

    Attributes
    ----------
    ids, random_ids : ndarray of int, shape (N,)
        The assigned IDs, and a random assignment (uniform over the frame's IDs).
    views : Views
        The poses the shares are measured on (drawn anew).
    ambiguous, random_ambiguous : ndarray of bool, shape (P,)
        Which of those views each assignment leaves ambiguous.
    """

    ids: np.ndarray
    random_ids: np.ndarray
    views: Views
    ambiguous: np.ndarray
    random_ambiguous: np.ndarray

    def shares(self, least: int) -> tuple[int, float, float]:
        """Views of ``least`` or more lights, and the share of them told apart by the
        assigned IDs and by the random ones."""
        n = int(np.sum(self.views.counts() >= least))
        return (
            n,
            identified_share(self.ambiguous, self.views, least),
            identified_share(self.random_ambiguous, self.views, least),
        )

    def reversed_neighbours(self, reverse: np.ndarray) -> tuple[int, int]:
        """Pairs of lights some view sees together whose IDs are each other's readout
        reversal, under the assigned and the random IDs."""
        together = seen_together(self.views, self.ids.size)
        out = []
        for ids in (self.ids, self.random_ids):
            out.append(sum(int(np.sum(reverse[ids[t]] == ids[f])) for f, t in enumerate(together)))
        return out[0] // 2, out[1] // 2


def assignment_report(
    positions_m: np.ndarray,
    up: np.ndarray,
    ids: np.ndarray,
    n_ids: int,
    views: Views,
    *,
    rng: np.random.Generator,
    tol_m: float = 0.05,
    one_missing: bool = True,
) -> Assignment:
    """How ``ids`` and a random assignment (drawn from ``rng``) tell ``views`` apart (see
    :func:`ambiguous_views`); ``views`` should be drawn anew, not those the IDs were
    searched on."""
    random_ids = rng.integers(0, n_ids, ids.size)
    amb = [
        ambiguous_views(positions_m, up, x, n_ids, views, tol_m=tol_m, one_missing=one_missing)
        for x in (ids, random_ids)
    ]
    return Assignment(np.asarray(ids), random_ids, views, amb[0], amb[1])
