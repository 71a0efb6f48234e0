"""numba kernels of the event pixel model and the ``events.txt`` formatter.

Each kernel fuses, in one pass over its pixels or events, what the NumPy reference
(:class:`roslan.events.reference.NumpyEventGenerator`) does in a dozen array passes; the float64
operations are the same and in the same order (numba does not contract to FMA nor reorder
without ``fastmath``), so the events are bit-identical. ``log``/``exp`` stay in NumPy (its
SIMD loops may differ from libm in the last ulp): the kernels write their arguments, in
the frame's precision (float32 for the renderer's float32 frames, float64 otherwise).

``nogil=True``: they run beside other threads (the event camera writes events.txt/h5 on
a background thread while the next frame renders; :mod:`roslan.io.background`).
``cache=True``: compiled once per machine (``__pycache__`` or numba's user cache dir).
"""

from __future__ import annotations

import numba
import numpy as np

from roslan.events.jit import kernel


@kernel
def log_exp_args(img, eps, s, logarg, exparg, want_log, want_exp):  # type: ignore[no-untyped-def]
    """``logarg = eps + max(I, 0)`` (the argument of ``L = log(eps + I)``) in the dtype of
    ``logarg`` (float32 arithmetic for a float32 ``img`` and ``eps``) and
    ``exparg = s * (clip(I, 0, 1) + 0.08) / 1.08`` (of the intensity-dependent low-pass),
    evaluated in float64 and rounded to the dtype of ``exparg``."""
    zero = img.dtype.type(0)
    for i in range(img.shape[0]):
        v = img[i]
        if want_log:
            logarg[i] = eps + (zero if v < zero else v)  # NaN stays NaN like np.maximum
        if want_exp:
            w = np.float64(v)
            c = 0.0 if w < 0.0 else (1.0 if w > 1.0 else w)
            exparg[i] = s * (c + 0.08) / 1.08


@numba.njit(inline="always")
def _test(i, s1, ref, c_pos, c_neg, sig, flag):  # type: ignore[no-untyped-def]
    sig[i] = s1
    r = ref[i]
    flag[i] = (r + c_pos[i] <= s1) | (r - c_neg[i] >= s1)


@kernel
def pixel_step(  # type: ignore[no-untyped-def]
    L, E, mode, a, lp, leak, tsec, ref, c_pos, c_neg, sig, flag
):
    """Low-pass, leak and threshold test of every pixel: updates ``lp`` in place, writes the
    new signal ``sig`` and ``flag`` (1 where the first level is reached).

    mode 0: ``lp = L``; 1: ``lp += a (L - lp)``; 2: ``lp += (1 - E) (L - lp)`` (E per pixel).
    ``leak`` (N,) log units per second, or (0,) for none. One branch-free loop per case (so
    that LLVM vectorizes it; the memory traffic of the pixel state is the cost).
    """
    n = L.shape[0]
    if leak.shape[0] > 0:
        if mode == 0:
            for i in range(n):
                x = L[i]
                lp[i] = x
                _test(i, x + leak[i] * tsec, ref, c_pos, c_neg, sig, flag)
        elif mode == 1:
            for i in range(n):
                x = lp[i] + a * (L[i] - lp[i])
                lp[i] = x
                _test(i, x + leak[i] * tsec, ref, c_pos, c_neg, sig, flag)
        else:
            for i in range(n):
                x = lp[i] + (1.0 - E[i]) * (L[i] - lp[i])
                lp[i] = x
                _test(i, x + leak[i] * tsec, ref, c_pos, c_neg, sig, flag)
    elif mode == 0:
        for i in range(n):
            x = L[i]
            lp[i] = x
            _test(i, x, ref, c_pos, c_neg, sig, flag)
    elif mode == 1:
        for i in range(n):
            x = lp[i] + a * (L[i] - lp[i])
            lp[i] = x
            _test(i, x, ref, c_pos, c_neg, sig, flag)
    else:
        for i in range(n):
            x = lp[i] + (1.0 - E[i]) * (L[i] - lp[i])
            lp[i] = x
            _test(i, x, ref, c_pos, c_neg, sig, flag)


@kernel
def compact(flag, cand, dense):  # type: ignore[no-untyped-def]
    """Indices of the set flags (0 or 1) into ``cand``; returns their number.

    ``dense``: branch-free (every index written, kept only where the flag is set), for
    candidates over ~3 % of the pixels, where a test per 8-flag word is an unpredictable
    branch (2x slower at 8 %); otherwise words of 8 clear flags are skipped (3x faster at
    1 %). Same result either way."""
    m = 0
    if dense:
        for i in range(flag.shape[0]):
            cand[m] = i
            m += flag[i]
        return m
    w = flag[: flag.shape[0] // 8 * 8].view(np.uint64)
    for j in range(w.shape[0]):
        if w[j] != 0:
            for i in range(8 * j, 8 * j + 8):
                cand[m] = i
                m += flag[i]
    for i in range(8 * w.shape[0], flag.shape[0]):
        cand[m] = i
        m += flag[i]
    return m


@kernel
def emit_first(  # type: ignore[no-untyped-def]
    cand, m, sig0, sig, ref, c_pos, c_neg, last, t0, dt_ns, refractory_ns, idx, t, p, n
):
    """The first level crossing of every candidate pixel ``cand[:m]`` (one exists: the
    flag) into ``idx``, ``t``, ``p`` from ``n`` on (room for ``m`` events needed); the
    instant the linear signal from ``sig0`` to ``sig`` crosses ``ref +- C``.

    Branch-free, and the write position does not depend on the refractory test: an event
    the refractory period drops is written with ``p = -1`` (a data-dependent branch or
    position per candidate cost ~40 % more). Pixels that also reach their second level
    are compacted in place to ``cand[:mm]`` for :func:`emit_more`, their ``ref``
    untouched; the others' ``ref`` moves to the level. ``last``: the pixels' last
    emitted event, updated. Returns ``(mm, n, dropped)``.
    """
    dtf = np.float64(dt_ns)
    dropped = 0
    mm = 0
    for j in range(m):
        i = cand[j]
        r = ref[i]
        s1 = sig[i]
        up = s1 > r
        cp_i = c_pos[i]
        cn_i = c_neg[i]
        cp = cp_i if up else cn_i
        sg = 1.0 if up else -1.0
        s0 = sig0[i]
        ds = s1 - s0
        lt = last[i]
        level = r + sg * (1 * cp)
        frac = (level - s0) / ds if ds != 0 else 1.0
        frac = min(max(frac, 0.0), 1.0) if frac == frac else frac  # np.clip keeps NaN
        tk = t0 + np.int64(np.rint(frac * dtf))
        keep = refractory_ns <= 0 or tk - lt >= refractory_ns
        idx[n] = i
        t[n] = tk
        p[n] = (1 if up else 0) if keep else -1
        n += 1
        dropped += 1 - keep
        last[i] = tk if keep else lt
        # level 2 not reached (most pixels): one crossing, exactly what the general count
        # of emit_more gives (it is >= 2 otherwise: the same test)
        more = not ((r + sg * (2 * cp) - s1) * sg > 0)
        ref[i] = r if more else level
        cand[mm] = i  # in place: mm <= j
        mm += more
    return mm, n, dropped


@kernel
def emit_more(  # type: ignore[no-untyped-def]
    cand, j0, mm, sig0, sig, ref, c_pos, c_neg, last, t0, dt_ns, refractory_ns, idx, t, p, n
):
    """The crossings after the first of the pixels ``cand[j0:mm]`` left by
    :func:`emit_first` (``ref`` still the old reference, ``last`` after the first event),
    in time order within a pixel, dropped ones with ``p = -1``; moves ``ref`` to the last
    level crossed (dropped events included: ESIM).

    Returns ``(j, n, dropped)``: the pixel it stopped at (``mm`` when done; earlier when
    the buffers are full, that pixel untouched), the events written, those dropped.
    """
    dtf = np.float64(dt_ns)
    cap = idx.shape[0]
    dropped = 0
    for j in range(j0, mm):
        i = cand[j]
        r = ref[i]
        s1 = sig[i]
        up = s1 > r
        cp = c_pos[i] if up else c_neg[i]
        sg = 1.0 if up else -1.0
        if (r + sg * (3 * cp) - s1) * sg > 0:
            # level 3 not reached (most of these pixels; level 2 is): two crossings, what
            # the general count gives, without its division
            cnt = np.int64(2)
        else:
            cnt = np.int64(np.floor(np.abs(s1 - r) / cp))
            # make the count agree exactly with the definition (level r +- n*C reached,
            # n+1 not)
            cnt -= np.int64((cnt > 1) & ((r + sg * (cnt * cp) - s1) * sg > 0))
            cnt = max(cnt, np.int64(1))
            cnt += np.int64((r + sg * ((cnt + 1) * cp) - s1) * sg <= 0)
        if n + cnt - 1 > cap:
            return j, n, dropped
        s0 = sig0[i]
        pol = 1 if up else 0
        ds = s1 - s0
        lt = last[i]
        for k in range(2, cnt + 1):
            level = r + sg * (k * cp)
            frac = (level - s0) / ds if ds != 0 else 1.0
            if frac == frac:  # np.clip keeps NaN
                frac = min(max(frac, 0.0), 1.0)
            tk = t0 + np.int64(np.rint(frac * dtf))
            keep = refractory_ns <= 0 or tk - lt >= refractory_ns
            idx[n] = i
            t[n] = tk
            p[n] = pol if keep else -1
            n += 1
            dropped += 1 - keep
            lt = tk if keep else lt
        last[i] = lt
        ref[i] = r + sg * (cnt * cp)
    return mm, n, dropped


@kernel
def shot_noise(  # type: ignore[no-untyped-def]
    sidx, traw, u, v, expl, eps, f, knee, smax, shot_on, shot_off, s1, ref, last, t0, idx, t, p, n
):
    """The shot-noise candidates (pixels ``sidx``, times ``t0 + 1 + traw``, ON where
    ``u < 0.5``) kept where ``v * smax < g * C_nom / C``, ``g = 1 - (1 - f) c`` (or
    ``1 / (1 + c / knee)`` where ``knee > 0``), ``c = clip(expl - eps, 0, 1)`` (``expl =
    exp(lp)`` of each candidate, ``shot_on``/``shot_off`` the per-pixel
    ``C_nom / C``) into ``idx``, ``t``, ``p`` from ``n`` on, sorted by pixel (stable: ties in
    draw order); each sets its pixel's ``ref`` to the signal ``s1`` and ``last`` to at least
    its time. Returns ``(n, ties)``: the new count, and whether two kept events share pixel
    and time (their keys would tie)."""
    n0 = n
    for j in range(sidx.shape[0]):
        i = sidx[j]
        on = u[j] < 0.5
        c = expl[j] - eps
        c = 0.0 if c < 0.0 else (1.0 if c > 1.0 else c)
        g = 1.0 / (1.0 + c / knee) if knee > 0.0 else 1.0 - (1.0 - f) * c
        ratio = shot_on[i] if on else shot_off[i]
        if v[j] * smax < g * ratio:
            tj = t0 + 1 + traw[j]
            k = n  # insertion, stable: after the kept events of pixels <= i
            while k > n0 and idx[k - 1] > i:
                idx[k] = idx[k - 1]
                t[k] = t[k - 1]
                p[k] = p[k - 1]
                k -= 1
            idx[k] = i
            t[k] = tj
            p[k] = 1 if on else 0
            n += 1
    ties = False
    for j in range(n0, n):
        i = idx[j]
        ref[i] = s1[i]
        last[i] = max(last[i], t[j])
        k = j - 1  # the run of this pixel, pairwise (runs are a few events long)
        while k >= n0 and idx[k] == i:
            ties |= t[k] == t[j]
            k -= 1
    return n, ties


@kernel
def pack_keys(t, idx, p, n_real, t0, ib, key):  # type: ignore[no-untyped-def]
    """``key = (t - t0, shot, pixel index, p)`` packed in bit fields (``ib`` bits of index);
    a dropped event (``p = -1``) gets the largest int64, so that it sorts last.

    Sorting these orders by time, then real events (by pixel index) before shot noise (by
    index): the stable time order of the reference's pixel-major events, as far as events
    that differ go (equal keys are identical events; the caller rules out shot-noise ties).
    """
    for j in range(t.shape[0]):
        shot = 1 if j >= n_real else 0
        k = ((((t[j] - t0) << 1 | shot) << ib | idx[j]) << 1) | np.int64(p[j] & 1)
        key[j] = k if p[j] >= 0 else np.iinfo(np.int64).max


@kernel
def unpack_keys(key, t0, ib, width, to, xo, yo, po):  # type: ignore[no-untyped-def]
    """Sorted keys of :func:`pack_keys` back to ``t``, ``x``, ``y``, ``p``."""
    imask = (np.int64(1) << ib) - 1
    inv_w = 1.0 / width
    for j in range(key.shape[0]):
        k = key[j]
        i = (k >> 1) & imask
        y = np.int64((i + 0.5) * inv_w)  # exact: far from an integer for i < 2**31
        to[j] = (k >> (ib + 2)) + t0
        xo[j] = i - y * width
        yo[j] = y
        po[j] = k & 1


@kernel
def gather_events(order, idx, t, p, width, to, xo, yo, po):  # type: ignore[no-untyped-def]
    """The events at positions ``order`` into ``to``, ``xo``, ``yo``, ``po`` (pixel index
    split into column and row)."""
    for j in range(order.shape[0]):
        o = order[j]
        i = idx[o]
        to[j] = t[o]
        xo[j] = i % width
        yo[j] = i // width
        po[j] = p[o]


_PAIRS = np.array([[48 + i // 10, 48 + i % 10] for i in range(100)], np.uint8)
"""(100, 2) ASCII digits of 00..99."""

_LEFT3 = np.array([[ord(c) for c in f"{i:<3d}"] + [len(str(i))] for i in range(1000)], np.uint8)
"""(1000, 4): the digits of 0..999 left-aligned in 3 bytes (then spaces), and their count."""

_ZERO3 = np.array([[ord(c) for c in f"{i:03d}"] + [3] for i in range(1000)], np.uint8)
"""(1000, 4): the digits of 000..999, zero-padded, and their count (3)."""

# The formatter's byte positions are unsigned (np.uint64, constants too: an unsigned index
# skips numba's negative-index wrap-around, a select per store).
_1 = np.uint64(1)
_2 = np.uint64(2)


@numba.njit(inline="always")
def _put3(out, k, row):  # type: ignore[no-untyped-def]
    """The three bytes of a table ``row`` at ``out[k:]``; the index after its ``row[3]``
    digits (a left-aligned number's trailing spaces are overwritten by what follows)."""
    out[k] = row[0]
    out[k + _1] = row[1]
    out[k + _2] = row[2]
    return k + np.uint64(row[3])


@numba.njit(inline="always")
def _put_int(out, k, v, pairs):  # type: ignore[no-untyped-def]
    """Decimal digits of ``v >= 0`` at ``out[k:]``; returns the index after them."""
    if v < 1000:  # (nearly every value: a table row, no digit loop)
        return _put3(out, k, _LEFT3[v])
    nd = np.uint64(1)
    p10 = np.int64(10)
    while nd < np.uint64(19) and v >= p10:
        nd += _1
        p10 *= 10
    e = k + nd
    j = e
    while v >= 100:
        q = v // 100
        r = v - q * 100
        out[j - _2] = pairs[r, 0]
        out[j - _1] = pairs[r, 1]
        v = q
        j -= _2
    if v >= 10:
        out[j - _2] = pairs[v, 0]
        out[j - _1] = pairs[v, 1]
    else:
        out[j - _1] = 48 + v
    return e


@kernel
def format_txt(t, x, y, p, out):  # type: ignore[no-untyped-def]
    """``'%d.%09d %d %d %d\\n'`` per event into ``out`` (uint8, long enough); t, x, y
    non-negative integers (t ns). Returns the number of bytes written."""
    pairs = _PAIRS
    zero3 = _ZERO3
    k = np.uint64(0)
    for j in range(t.shape[0]):
        v = t[j]
        sec = v // 1_000_000_000
        frac = v - sec * 1_000_000_000
        k = _put_int(out, k, sec, pairs)
        out[k] = 46  # '.'
        # nine digits, zero-padded: three groups of three
        hi = frac // 1_000_000
        rest = frac - hi * 1_000_000
        mid = rest // 1000
        _put3(out, k + _1, zero3[hi])
        _put3(out, k + np.uint64(4), zero3[mid])
        _put3(out, k + np.uint64(7), zero3[rest - mid * 1000])
        out[k + np.uint64(10)] = 32
        k = _put_int(out, k + np.uint64(11), np.int64(x[j]), pairs)
        out[k] = 32
        k = _put_int(out, k + _1, np.int64(y[j]), pairs)
        out[k] = 32
        out[k + _1] = 49 if p[j] > 0 else 48
        out[k + _2] = 10
        k += np.uint64(3)
    return k


@kernel
def pack_events(t, offset, x, y, p, first, rest):  # type: ignore[no-untyped-def]
    """``dvs_msgs/Event`` records (structured arrays, little endian): event 0 into
    ``first`` (1,), the others into ``rest`` (N - 1,) (fields ``x, y, sec, nsec, p``; any
    padding between them is left as it is). Stamps ``t + offset`` ns split into sec / nsec
    (floor; low 32 bits of each), x, y (low 16 bits), polarity 1 where ``p > 0``. One
    store per field (the structured-array assignments of NumPy take a pass per field)."""
    if t.shape[0]:
        _pack_records(t[:1], offset, x[:1], y[:1], p[:1], first)
        _pack_records(t[1:], offset, x[1:], y[1:], p[1:], rest)


@numba.njit(inline="always")
def _pack_records(t, offset, x, y, p, rec):  # type: ignore[no-untyped-def]
    ns = np.int64(1_000_000_000)
    m32 = np.int64(0xFFFFFFFF)
    for j in range(t.shape[0]):
        tt = t[j] + offset
        sec = tt // ns
        r = rec[j]
        r.x = np.uint16(np.int64(x[j]) & 0xFFFF)
        r.y = np.uint16(np.int64(y[j]) & 0xFFFF)
        r.sec = np.uint32(sec & m32)
        r.nsec = np.uint32((tt - sec * ns) & m32)
        r.p = 1 if p[j] > 0 else 0
