r"""Where a run is driven: the lanes of :mod:`dryfric_jax.excursions` in rounds, from the host.

:class:`Lanes` keeps one batch of lanes on the devices between rounds.  A *paused* round runs
every lane for the same number of blocks and pauses it, its in-flight excursion kept for the next
round, so no lane waits for another.  The *final* round starts no new excursion: each lane
finishes the one in flight and raises its termination flag (unbiased: the number of excursions a
lane starts is a stopping time; :mod:`dryfric_jax.excursions`).  Its tail (the few lanes still
finishing a long excursion) runs on a compacted batch of lanes, each lane keeping its key and block
count, so compaction changes no result (:meth:`Lanes._compact_tail`).

:func:`simulate_long_excursions` sizes the rounds from the steps per excursion measured so far,
runs them until N excursions (or a precision target, ``max_work`` or ``max_time``), then the
final round; progress, deadlines and Ctrl-C act between rounds and between a final round's calls,
and the results of completed rounds are never lost.
"""
from __future__ import annotations

import contextlib
import dataclasses
import sys
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import NamedSharding, PartitionSpec, SingleDeviceSharding

from .interrupts import held_interrupts, interrupt_noted
from .excursions import (
    BLOCK, SEEK, STAT_NAMES, _events_layout, _Lane, _run_round, _sharded_round, init_lanes, lanes_for,
)

# final round: the tail runs on lanes / COMPACT lanes once at most that many are still in flight
# (devices with at least COMPACT_MIN_PER_DEVICE lanes)
COMPACT = 8
COMPACT_MIN_PER_DEVICE = 64
# lane-steps (idle lanes included) of one call of a final round (Lanes._call): ~4 s on 2 CPU cores
FINAL_CALL_LANE_STEPS = 2**27
#: once the wall time of a block is known (the last call's), a round's call (paused or final) is also cut to about
#: this many seconds, but to no fewer than FINAL_CALL_MIN_BLOCKS blocks: the lane-steps alone made calls of 15-100 s
#: with few lanes (the PDMP at tau' = 1e-3, 8 lanes or 1), past the grace a Ctrl-C is promised (a hard-cases audit),
#: and a paused round of up to 2^26 lane-steps on one such lane made a first Ctrl-C or SIGTERM wait for its end
#: (SIGTERM 45 s into a run on one PDMP lane, tau' = 1e-3: 74 s to exit, now 22 s, the 20 s grace included)
FINAL_CALL_S = 2.0
FINAL_CALL_MIN_BLOCKS = 64
# lane-steps of a paused round at most (simulate_long_excursions; a few seconds on a CPU, never below 4
# blocks): progress, max_time and Ctrl-C act between rounds.  On an H200 2^26 is ~7 ms of work, so a run
# at 2^18 lanes and K = 1024 makes rounds of 4 blocks (PERFORMANCE.md "On an H200"; device_check --round-steps)
ROUND_LANE_STEPS = 2**26
#: with ``max_time``, the final round is cut at this multiple of it (:func:`simulate_long_excursions`)
FINAL_DEADLINE = 2.0
#: after a first Ctrl-C (or SIGTERM in the CLI), the final round that finishes the excursions in flight
#: is cut this many seconds later (between calls; the cut ones are reported as truncated): without it, a
#: run far harder than planned (Gamma = 1e8 at Fig. 3's point) finished them for over 10 minutes, silent
INTERRUPT_GRACE_S = 20.0
# > 0 inside abandon_on_interrupt(): a Ctrl-C then ends the run at once (KeyboardInterrupt), no final round
_ABANDON = [0]


def after_run():
    """The hold for the last steps of a run that has finished (its result formed from the sums):
    :func:`~dryfric_jax.interrupts.interrupt_noted`, whose list says whether a Ctrl-C or SIGTERM came; within
    :func:`abandon_on_interrupt` none (a caller that keeps finished runs only takes the Ctrl-C at once)."""
    return interrupt_noted() if not _ABANDON[0] else contextlib.nullcontext([])


def noted_late(result, what: str):
    """``result`` (an estimate's or a count's) marked as interrupted, with a note said as a warning, where a Ctrl-C
    or SIGTERM came as the ``what`` ("run", "count") ended (:func:`after_run`): the numbers are the whole run's."""
    from .api import DryfricWarning  # (api imports this module)

    note = f"interrupted as the {what} ended (stopped by {result.stopped_by}): the result is the whole {what}'s"
    warnings.warn(note, DryfricWarning, stacklevel=3)
    return dataclasses.replace(result, stopped_by="interrupted", warnings=type(result.warnings)((*result.warnings,
                                                                                                 note)))


@contextmanager
def abandon_on_interrupt():
    """Within it, a Ctrl-C (SIGTERM under ``dryfric``) inside :func:`simulate_long_excursions` raises
    ``KeyboardInterrupt`` at once instead of finishing the excursions in flight: for callers that keep
    finished runs only (a sweep's points, a figure's runs), which threw that result away after waiting up
    to :data:`INTERRUPT_GRACE_S` for it, and said "finishing the ... excursions in flight" (a sweep audit)."""
    _ABANDON[0] += 1
    try:
        yield
    finally:
        _ABANDON[0] -= 1


@dataclass
class ExcursionStats:
    """Per-lane sums over complete long excursions, nondimensional (U in u0, t in tau0).

    ``stats[:, k]`` is the lane sum of ``STAT_NAMES[k]``; lanes are independent, so any
    grouping of lanes is an independent replicate.
    """

    stats: np.ndarray  # (lanes, len(STAT_NAMES))
    n_truncated: int  # excursions closed by the work bound (not in stats)
    useful_steps: int  # lane-steps (events) that advanced an excursion (seeks excluded)
    slot_steps: int  # lane-steps paid for, idle lanes included
    n_unfinished: int = 0  # lanes the block bound stopped (never expected; reported, not hidden)
    n_in_flight: int = 0  # excursions running when the round paused (closed by a final round)
    lane_steps: np.ndarray | None = None  # (lanes,) useful steps (DI) or events (PDMP) per lane

    @property
    def n_excursions(self) -> int:
        return int(round(self.stats[:, 0].sum()))

    def total(self) -> dict:
        return dict(zip(STAT_NAMES, self.stats.sum(0)))


def _now() -> float:
    """The clock of ``max_time`` and the final round's deadline (a test replaces it)."""
    return time.perf_counter()


class Lanes:
    """Persistent lanes of one chain: rounds continue the lanes' chains where they paused.

    ``advance(key, budget)`` runs a *paused* round: every lane runs ``ceil(budget / block)``
    blocks (``budget`` steps, less the idle rest of a block after an event in the ``"wait"``
    layout) and pauses, its in-flight excursion kept for the next round, so no lane waits for
    another.  ``finish(key, budget)`` runs the *final* round: after ``budget`` steps a lane starts
    no new excursion, finishes the one in flight and raises its termination flag.  Only the
    final round has idle lanes (waiting for the slowest in-flight excursion).

    Lanes are sharded over all local devices (CPU devices from
    ``--xla_force_host_platform_device_count``, or GPUs).  Round keys: ``split(key, lanes)`` per
    lane, and ``fold_in(lane_key, block)`` per block.  Where the device count does not divide the
    lane count, pad lanes fill the last device: each repeats a real lane's key (its chain is that
    lane's, step for step) and is dropped from the statistics, so the estimate does not depend on
    the device count (on 3 devices 512 lanes used to become 513 live ones, another sample).

    ``paid`` is the work the run's bounds see (``max_work``): the slots of the paused rounds (every
    real lane runs the same blocks) plus the real lanes' steps in the final rounds, whose idle
    slots depend on how the lanes are split over the devices; ``slot_steps`` is what the devices
    paid, pad lanes and idle slots included.
    """

    def __init__(self, chain, n_lanes: int, *, block: int = BLOCK, max_steps: int = 10**8, events: str | None = None,
                 compact: bool = True):
        self.devices = tuple(jax.local_devices())
        nd = len(self.devices)
        self.n_real = n_lanes
        # lanes in the layout, pad lanes included; at least 2 per device: XLA:CPU compiled a one-lane shard to other
        # arithmetic (the last bits of M0 and the CIs changed with the device count)
        self.n = max(2, -(-n_lanes // nd)) * nd
        self.chain, self.block, self.max_steps = chain, block, max_steps
        self.events = _events_layout(self.devices, chain, events)
        # the final round's tail runs on n / COMPACT lanes (see _compact_tail)
        self.compact = compact and self.n // nd >= COMPACT_MIN_PER_DEVICE
        self.slot_steps, self.paid, self.last, self.rounds = 0, 0, None, 0
        self._block_s = None  # wall seconds of one block in the last call (at its width): sizes a final round's calls
        if nd > 1:
            self._f, self._sharding = _sharded_round(self.devices, block, self.events)
            self._rep = NamedSharding(self._sharding.mesh, PartitionSpec())
        else:
            self._f = partial(_run_round, block=block, events=self.events)
            self._sharding = self._rep = SingleDeviceSharding(self.devices[0])
        # the chain is placed on every device once, the keys once per round, and a call passes the
        # lanes it got from the last one: a one-block paused round took 4.3 -> 3.1 ms (2 CPU devices,
        # 512 lanes; the block itself ~0.3 ms; a run of N = 1e4 makes ~8 rounds), the same numbers
        self._chain = jax.device_put(chain, self._rep)
        self.lane = init_lanes(chain, self.n, self._sharding)

    def _call(self, lane, keys, b0, budget, finish, min_active, fresh, deadline=None):
        """The jitted round on ``lane`` (any multiple of the device count); returns the lanes and
        the blocks each device ran.

        A round runs in calls of about ``FINAL_CALL_S`` seconds once the last call has timed a block (but at least
        ``FINAL_CALL_MIN_BLOCKS`` blocks), and a final round also in calls of at most ``FINAL_CALL_LANE_STEPS``
        lane-steps each (a paused round's budget bounds it), each continuing the last, so that a Ctrl-C acts
        between calls: the in-flight excursions of a heavy-tailed case can take minutes to finish, and one call
        would not return before they have (seen: > 6 min at Fig. 3's tau = 1 s, Gamma = 1); a paused round's
        ~50 s on one PDMP lane.  The result is the same as one call (tested): a paused round's length, which
        fixes the random streams, is its budget's blocks however they are split.
        Past ``deadline`` (:func:`_now`) no further call starts: the lanes still running
        stay unfinished (``n_unfinished``, reported as truncated)."""
        nd = len(self.devices)
        per_dev = keys.shape[0] // nd
        most = max(1, FINAL_CALL_LANE_STEPS // (keys.shape[0] * self.block)) if finish else np.iinfo(np.int64).max
        args = (np.int64(budget), np.int64(self.max_steps), np.bool_(finish), np.int64(min_active))
        b0, total = np.asarray(b0, np.int64), np.zeros(nd, np.int64)
        keys = jax.device_put(keys, self._sharding)  # once per round (the lanes are already on their devices)
        while True:
            cap = most  # by time too where a block's time is known (a call that compiled overstates it: shorter calls)
            if self._block_s is not None:
                cap = min(most, max(FINAL_CALL_MIN_BLOCKS, int(FINAL_CALL_S / max(self._block_s, 1e-12))))
            t = time.perf_counter()
            lane, nb = self._call_once(lane, keys, b0, args + (np.bool_(fresh), np.int64(cap)))
            if nb.max() > 0:
                self._block_s = (time.perf_counter() - t) / int(nb.max())
            self.slot_steps += int(nb.sum()) * self.block * per_dev
            total, b0, fresh = total + nb, b0 + np.repeat(nb, per_dev), False
            # every device stopped on its own condition (a paused round: its blocks all run), or the deadline passed
            if (not (nb >= cap).any() or (not finish and b0.min() >= -(-budget // self.block))
                    or (deadline is not None and _now() >= deadline)):
                return lane, total

    def _call_once(self, lane, keys, b0, args):
        """One call of the jitted round (``args``: budget .. cap of :func:`_round_impl`); returns
        the lanes and the blocks each device ran (on the host)."""
        b0, args = jax.device_put((np.asarray(b0, np.int64), args), (self._sharding, self._rep))
        lane, nb = self._f(self._chain, lane, keys, b0, *args)
        return lane, np.asarray(jax.device_get(nb))

    def _round(self, key, budget, finish, deadline=None) -> ExcursionStats:
        """A paused or final round (a final one compacts its tail, :meth:`_compact_tail`)."""
        keys = jax.random.split(key, self.n_real)
        if self.n > self.n_real:  # pad lanes repeat real lanes' keys (dropped below)
            keys = jnp.concatenate([keys, keys[np.arange(self.n - self.n_real) % self.n_real]])
        nd = len(self.devices)
        small = -(-(self.n // nd) // COMPACT) if finish and self.compact else 0  # per device, compacted
        lane, nb = self._call(self.lane, keys, np.zeros(self.n, np.int64), budget, finish, small, True, deadline)
        # the tail is further calls: none starts past the deadline (it ran one, compiling a new shape:
        # 2 x 4-5 s past a 3-s max_time on 2 cores)
        tail = small and (deadline is None or _now() < deadline)
        # a compacted round's lanes stay on the host: a next round's first call places them (a final
        # round is mostly the last)
        host = lane = self._compact_tail(jax.device_get(lane), keys, nb, budget, small, deadline) if tail else lane
        stats, n_trunc, steps, done, phase, work = jax.device_get(
            (host.stats, host.n_trunc, host.steps, host.done, host.phase, host.work))
        r = self.n_real  # the real lanes only: pad lanes are copies
        stats, n_trunc, steps, done, phase, work = (np.stack(stats, axis=1)[:r], np.asarray(n_trunc)[:r],
                                                    np.asarray(steps)[:r], np.asarray(done)[:r],
                                                    np.asarray(phase)[:r], np.asarray(work)[:r])
        paid = self.paid + (int(work.sum()) if finish else int(nb.max()) * self.block * r)
        last = ExcursionStats(stats, int(n_trunc.sum()), int(steps.sum()), self.slot_steps,
                              int((~done).sum()), int((phase != SEEK).sum()), steps)
        # the round is kept only once it has completed, and all of it or none: a Ctrl-C before this keeps the
        # previous state (the round reruns with the same key), and one here waits until the round is kept.  The
        # lanes set before the stats were built, or before the caller counted the round, made a Ctrl-C there run
        # the next round on the round's key again (a reproducibility audit); the caller's key is ``rounds``
        with held_interrupts():
            self.paid, self.lane, self.last, self.rounds = paid, lane, last, self.rounds + 1
        return last

    def _compact_tail(self, host: _Lane, keys, nb, budget, small: int, deadline=None) -> _Lane:
        """The final round's tail on a compacted batch.  The first part of the round stopped once
        at most ``small`` lanes of each device were still finishing their in-flight excursion
        (``host``, on the host); those lanes, padded with finished ones, continue as a batch of
        ``small`` lanes per device, so the tail of heavy-tailed excursions no longer pays for the
        idle lanes.  Each lane keeps its key and its block count, so it runs exactly the chain it
        would have run without compaction (the results are the same, tested).  Returns the
        round's lanes, on the host."""
        done = np.asarray(host.done)
        active, m = np.flatnonzero(~done), small * len(self.devices)
        if active.size > m:  # only if the block bound stopped a device: nothing to compact
            return host
        # finished lanes pad the batch; they do nothing and are written back unchanged
        sel = np.concatenate([active, np.flatnonzero(done)[: m - active.size]])
        b0 = nb[sel // (self.n // len(self.devices))]  # the blocks lane sel[j] has run in this round
        sub = jax.device_put(jax.tree_util.tree_map(lambda a: np.asarray(a)[sel], host), self._sharding)
        sub, _ = self._call(sub, keys[sel], b0, budget, True, 0, False, deadline)

        def put_back(full, part):
            full = np.array(full)
            full[sel] = part
            return full

        return jax.tree_util.tree_map(put_back, host, jax.device_get(sub))

    def advance(self, key, budget: int) -> ExcursionStats:
        return self._round(key, budget, False)

    def finish(self, key, budget: int = 0, deadline: float | None = None) -> ExcursionStats:
        """The final round; past ``deadline`` (:func:`_now`) it stops between calls, and
        the excursions still in flight are left unfinished (``n_unfinished``)."""
        return self._round(key, budget, True, deadline)


def run_round(chain, key, lanes: int, budget: int, *, block: int = BLOCK, max_steps: int = 10**8,
              finish_in_flight: bool = True, events: str | None = None) -> ExcursionStats:
    """One final round on fresh lanes: each lane refills until ``budget`` steps, then finishes its
    in-flight excursion.  ``finish_in_flight=False`` drops it instead (biased; for the tests)."""
    ln = Lanes(chain, lanes, block=block, max_steps=max_steps, events=events)
    res = ln._round(key, budget, finish_in_flight)
    if not finish_in_flight:
        res.n_in_flight = 0  # dropped
    return res


def work_per_excursion(work: float, closed: int, in_flight: int) -> float:
    """Lane-steps (events) paid per excursion so far, each in-flight one counted as one: a lower
    estimate (the round sizing of :func:`simulate_long_excursions`; ``api.time_left`` and the
    ProjectionWarning)."""
    return work / (closed + in_flight)


def simulate_long_excursions(chain, key, n_excursions: int, *, lanes: int | None = None,
                             chunk_lanes: int | None = None, block: int = BLOCK, max_steps: int = 10**8,
                             pilot_budget: int = 1024, more=None, max_time: float | None = None,
                             max_work: float | None = None, round_lane_steps: int | None = None, progress=None):
    """Long excursions of ``chain`` (DI or PDMP) in rounds of persistent lanes, until enough.

    Round r uses ``fold_in(key, r)``.  Paused rounds (:class:`Lanes`) run every lane for the
    same number of steps, so no lane idles; the first has a small pilot budget, later ones size
    the budget from the measured steps per excursion, capped at ``round_lane_steps`` lane-steps
    per round (default ``ROUND_LANE_STEPS``, a few seconds on a CPU) so that progress,
    ``max_time`` and Ctrl-C act between rounds.  Once the closed plus in-flight excursions reach
    the target, a final round finishes every in-flight excursion and starts none (unbiased: the
    number of excursions a lane starts is a stopping time).  The cap is a step count, not a
    time, so the same seed and settings give bit-identical results (except when ``max_time``
    stops the run).

    Args:
        chain: a :class:`~dryfric_jax.di.DIModel` or :class:`~dryfric_jax.pdmp.PDMPModel`.
        key: a ``jax.random`` key.
        n_excursions: closed (complete or truncated) excursions to reach at least.
        lanes: lanes (default :func:`lanes_for`; a power of two up to ``chunk_lanes``).
        block: steps per while-iteration, their random numbers drawn at once.
        max_steps: work bound per excursion; excursions reaching it are counted as truncated.
        more: optional ``more(stats) -> int``: further excursions wanted once ``n_excursions``
            are reached (0 to stop); used for precision targets.
        max_time: stop (after finishing the in-flight excursions) once this many seconds passed.
            The final round that finishes them is cut once ``FINAL_DEADLINE * max_time`` seconds
            have passed (between calls of a few seconds): the excursions still in flight are
            then left unfinished (``n_unfinished``, reported as truncated), so the run takes
            at most about twice ``max_time``, plus one round and one call (``round_lane_steps``
            lane-steps, and ``FINAL_CALL_LANE_STEPS`` lane-steps or ~``FINAL_CALL_S`` once a block is timed; no
            compacted tail starts past the deadline).
        max_work: stop the same way once the lanes have paid for this many lane-steps.
        progress: optional ``progress(stats)`` called after every round.

    Returns:
        ``(stats, stopped_by)`` with ``stopped_by`` in ``{"n_excursions", "target", "max_time",
        "interrupted", "work_bound"}``.  Completed rounds are never lost: on Ctrl-C the in-flight
        excursions are finished (a second Ctrl-C drops them, see ``n_in_flight``), within
        :data:`INTERRUPT_GRACE_S` of the first Ctrl-C (those still running then are left unfinished);
        under :func:`abandon_on_interrupt` the Ctrl-C is raised at once.
        A first Ctrl-C that comes during the final round (a Ctrl-C acts between its calls) runs that
        round again from its start, which gives the same excursions where the grace suffices (fewer
        where the round needed longer); it was taken for the second.
    """
    if n_excursions < 1:
        raise ValueError(f"n_excursions must be >= 1 (got {n_excursions})")
    lanes = lanes or lanes_for(n_excursions, chunk_lanes)
    round_lane_steps = ROUND_LANE_STEPS if round_lane_steps is None else round_lane_steps
    ln = Lanes(chain, lanes, block=block, max_steps=max_steps)
    closed = lambda st: st.n_excursions + st.n_truncated  # truncated count too: work stays bounded
    total, budget, want, stopped = None, pilot_budget, n_excursions, "n_excursions"
    t_start = _now()
    # the final round finishes the excursions in flight; past 2 max_time it is cut between calls
    deadline = None if max_time is None else t_start + FINAL_DEADLINE * max_time
    while True:  # paused rounds, then a final round; again if the target moved (precision targets)
        try:
            while True:
                total = ln.advance(jax.random.fold_in(key, ln.rounds), budget)
                if progress is not None:
                    progress(total)
                done = closed(total)
                if done + total.n_in_flight >= want and more is not None:
                    extra = int(more(total))
                    want = done + extra if extra > 0 else want
                if done + total.n_in_flight >= want:
                    break
                if max_time is not None and _now() - t_start >= max_time:
                    stopped = "max_time"
                    break
                if max_work is not None and ln.paid >= max_work:
                    stopped = "work_bound"
                    break
                if done == 0:
                    # nothing closed yet: a longer pilot, within a round's lane-steps (an excursion far
                    # longer than planned made one pilot round run for minutes past max_time)
                    budget = min(budget * 4, max(round_lane_steps // ln.n_real, 4 * block))
                    if ln.paid > 64 * max_steps * ln.n_real:
                        stopped = "work_bound"
                        break
                else:
                    # in-flight excursions count as one each: an underestimate, so rounds never overshoot
                    per_exc = work_per_excursion(total.useful_steps, done, total.n_in_flight)
                    budget = int(np.ceil((want - done - total.n_in_flight) * per_exc / ln.n_real))
                    budget = max(4 * block, int(per_exc) // 4, min(budget, round_lane_steps // ln.n_real))
                if max_work is not None:  # never plan past the work cap
                    budget = max(block, min(budget, int((max_work - ln.paid) // ln.n_real) + block))
        except KeyboardInterrupt:
            stopped = "interrupted"
            total = ln.last  # the rounds kept (Lanes._round), the last one's too if the Ctrl-C came as it returned
            if total is None or _ABANDON[0]:
                raise
            deadline = _grace(deadline, total.n_in_flight)
        first_ctrl_c = stopped != "interrupted"  # the run's first Ctrl-C may still come, in this round
        while True:
            kept = ln.rounds
            try:
                total = ln.finish(jax.random.fold_in(key, ln.rounds), deadline=deadline)
                if total.n_unfinished and deadline is not None and stopped != "interrupted" and _now() >= deadline:
                    stopped = "max_time"  # the deadline cut the final round (whatever ended the rounds)
            except KeyboardInterrupt:
                stopped = "interrupted"
                if _ABANDON[0]:
                    raise
                if ln.rounds > kept:  # the Ctrl-C came as the final round returned: it is kept, and complete
                    total = ln.last
                elif first_ctrl_c:  # the first Ctrl-C finishes the in-flight excursions: the final round
                    first_ctrl_c = False  # runs again from its start (same key, lanes unchanged: same chains)
                    deadline = _grace(deadline, total.n_in_flight)
                    continue
                # second Ctrl-C: keep the closed excursions, in-flight ones dropped
            break
        if stopped != "n_excursions" or more is None:
            break
        # the final round added the in-flight excursions: check the target on the final sums
        extra = int(more(total))
        if extra <= 0:
            stopped = "target"
            break
        want = closed(total) + extra
    return total, stopped


def _grace(deadline: float | None, in_flight: int) -> float:
    """The final round's deadline after a first Ctrl-C: at most :data:`INTERRUPT_GRACE_S` from now.
    Says so on stderr (the run otherwise went silent until it ended), on a line of its own (a terminal's
    progress line is cleared first)."""
    now = _now()
    new = now + INTERRUPT_GRACE_S if deadline is None else min(deadline, now + INTERRUPT_GRACE_S)
    clear = "\r\x1b[K" if sys.stderr.isatty() else ""
    print(f"{clear}dryfric: interrupted: finishing the {in_flight} excursions in flight for at most "
          f"{max(new - now, 0.0):.3g} s (any still running then are reported as truncated); interrupt again to drop "
          "them", file=sys.stderr, flush=True)
    return new


def steps_per_excursion(chain, key, *, lanes: int = 256, budget: int = 4096, block: int = BLOCK,
                        max_steps: int = 10**8) -> float:
    """Pilot estimate of the mean number of steps (events) of one long excursion."""
    while True:
        res = run_round(chain, key, lanes, budget, block=block, max_steps=max_steps)
        if res.n_excursions >= lanes or budget > 64 * max_steps:
            return res.useful_steps / max(res.n_excursions, 1)
        budget *= 4


def simulate_replicates(chain, key, n_replicates: int, n_per_replicate: int, *,
                        lanes_per_replicate: int = 16, block: int = BLOCK, max_steps: int = 10**8):
    """Independent replicates of about ``n_per_replicate`` excursions each (for calibration).

    One pilot round (discarded) measures the steps per excursion; then one final round runs
    ``n_replicates * lanes_per_replicate`` fresh lanes with a budget of ``1.05 n_per_replicate``
    mean excursions per replicate.  Replicate k is lanes ``[k L, (k+1) L)``.
    """
    per = steps_per_excursion(chain, jax.random.fold_in(key, 0), block=block, max_steps=max_steps)
    budget = int(np.ceil(1.05 * n_per_replicate * per / lanes_per_replicate))
    return run_round(chain, jax.random.fold_in(key, 1), n_replicates * lanes_per_replicate, budget, block=block,
                     max_steps=max_steps)
