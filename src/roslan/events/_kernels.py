"""numba kernels of the event pixel model and the ``events.txt`` formatter.

Each kernel fuses, in one pass over its pixels or events, what the NumPy reference
(:class:`roslan.events.model.NumpyEventGenerator`) does in a dozen array passes; the float64
operations are the same and in the same order (numba does not contract to FMA nor reorder
without ``fastmath``), so the events are bit-identical. ``log``/``exp`` stay in NumPy (its
SIMD loops may differ from libm in the last ulp): the kernels write their arguments, in
the frame's precision (float32 for the renderer's float32 frames, float64 otherwise).

``nogil=True``: the simulation runs event generation in a thread beside rendering.
``cache=True``: compiled once per machine (``__pycache__`` or numba's user cache dir).
"""

from __future__ import annotations

import numba
import numpy as np

from roslan.jit import kernel


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
def compact(flag, cand):  # type: ignore[no-untyped-def]
    """Indices of the set flags (0 or 1) into ``cand``; returns their number.

    Branch-free (every index written, kept only where the flag is set): candidates are
    ~1-10 % of the pixels, scattered, so any test per pixel or per word of flags is an
    unpredictable branch (skipping clear 8-flag words cost 2x this on real frames)."""
    m = 0
    for i in range(flag.shape[0]):
        cand[m] = i
        m += flag[i]
    return m


@kernel
def emit_crossings(  # type: ignore[no-untyped-def]
    cand, j0, m, sig0, sig, ref, c_pos, c_neg, last, t0, dt_ns, refractory_ns, idx, t, p, n
):
    """Every level crossing of the candidate pixels ``cand[j0:m]`` into ``idx``, ``t``, ``p``
    from ``n`` on, pixel-major and in time order within a pixel (the instant the linear
    signal from ``sig0`` to ``sig`` crosses the level); moves ``ref`` to the last level and
    applies the refractory period (``last``: the pixels' last emitted event).

    Returns ``(j, n, dropped)``: the candidate it stopped at (``m`` when done; earlier when
    the buffers are full, that pixel untouched), the events written, those dropped.
    """
    dtf = np.float64(dt_ns)
    cap = idx.shape[0]
    dropped = 0
    for j in range(j0, m):
        i = cand[j]
        r = ref[i]
        s1 = sig[i]
        up = s1 > r
        cp_i = c_pos[i]
        cn_i = c_neg[i]
        cp = cp_i if up else cn_i
        sg = 1.0 if up else -1.0
        if (r + sg * (2 * cp) - s1) * sg > 0:
            # level 2 not reached (most candidates; level 1 is, by the flag): one crossing,
            # exactly what the general count below gives, without its division
            cnt = np.int64(1)
        else:
            cnt = np.int64(np.floor(np.abs(s1 - r) / cp))
            # make the count agree exactly with the definition (level r +- n*C reached,
            # n+1 not) (branch-free: the mismatch makes these unpredictable)
            cnt -= np.int64((cnt > 1) & ((r + sg * (cnt * cp) - s1) * sg > 0))
            cnt = max(cnt, np.int64(1))
            cnt += np.int64((r + sg * ((cnt + 1) * cp) - s1) * sg <= 0)
        if n + cnt > cap:
            return j, n, dropped
        s0 = sig0[i]
        pol = 1 if up else 0
        ds = s1 - s0
        lt = last[i]
        n_pix = n
        for k in range(1, cnt + 1):
            level = r + sg * (k * cp)
            frac = (level - s0) / ds if ds != 0 else 1.0
            if frac == frac:  # np.clip keeps NaN
                frac = min(max(frac, 0.0), 1.0)
            tk = t0 + np.int64(np.rint(frac * dtf))
            # branch-free: write always, advance only for a kept event
            keep = refractory_ns <= 0 or tk - lt >= refractory_ns
            idx[n] = i
            t[n] = tk
            p[n] = pol
            n += keep
            lt = tk if keep else lt
        dropped += cnt - (n - n_pix)
        last[i] = lt
        ref[i] = r + sg * (cnt * cp)
    return m, n, dropped


@kernel
def apply_shot_noise(idx, t, p, ref, c_pos, c_neg, last):  # type: ignore[no-untyped-def]
    """Shot-noise events reset their pixels like real ones, in event order (``np.add.at``)."""
    for j in range(idx.shape[0]):
        i = idx[j]
        ref[i] += c_pos[i] if p[j] == 1 else -c_neg[i]
        last[i] = max(last[i], t[j])


@kernel
def has_ties(t, idx):  # type: ignore[no-untyped-def]
    """Whether two events share both time and pixel (``idx`` sorted)."""
    for j in range(1, idx.shape[0]):
        if idx[j] == idx[j - 1]:
            k = j - 1  # the run of this pixel, pairwise (runs are a few events long)
            while k >= 0 and idx[k] == idx[j]:
                if t[k] == t[j]:
                    return True
                k -= 1
    return False


@kernel
def pack_keys(t, idx, p, n_real, t0, ib, key):  # type: ignore[no-untyped-def]
    """``key = (t - t0, shot, pixel index, p)`` packed in bit fields (``ib`` bits of index).

    Sorting these orders by time, then real events (pixel-major: by index) before shot
    noise (by index): the stable time order of the events, as far as events that differ go
    (equal keys are identical events; the caller rules out shot-noise ties).
    """
    for j in range(t.shape[0]):
        shot = 1 if j >= n_real else 0
        key[j] = ((((t[j] - t0) << 1 | shot) << ib | idx[j]) << 1) | np.int64(p[j])


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
def sort_keys(t, t0, shift, key):  # type: ignore[no-untyped-def]
    """``key = (t - t0) << shift | position``: unique keys whose unstable sort is the
    stable time order."""
    for j in range(t.shape[0]):
        key[j] = ((t[j] - t0) << shift) | j


@kernel
def gather_events(key, mask, idx, t, p, width, to, xo, yo, po):  # type: ignore[no-untyped-def]
    """The events in sorted-key order (position ``key & mask``) into ``to``, ``xo``, ``yo``,
    ``po`` (pixel index split into column and row)."""
    for j in range(key.shape[0]):
        o = key[j] & mask
        i = idx[o]
        to[j] = t[o]
        xo[j] = i % width
        yo[j] = i // width
        po[j] = p[o]


_PAIRS = np.array([[48 + i // 10, 48 + i % 10] for i in range(100)], np.uint8)
"""(100, 2) ASCII digits of 00..99."""


@numba.njit(inline="always")
def _put_int(out, k, v, pairs):  # type: ignore[no-untyped-def]
    """Decimal digits of ``v >= 0`` at ``out[k:]``; returns the index after them."""
    nd = 1
    p10 = np.int64(10)
    while nd < 19 and v >= p10:
        nd += 1
        p10 *= 10
    e = k + nd
    j = e
    while v >= 100:
        q = v // 100
        r = v - q * 100
        out[j - 2] = pairs[r, 0]
        out[j - 1] = pairs[r, 1]
        v = q
        j -= 2
    if v >= 10:
        out[j - 2] = pairs[v, 0]
        out[j - 1] = pairs[v, 1]
    else:
        out[j - 1] = 48 + v
    return e


@kernel
def format_txt(t, x, y, p, out):  # type: ignore[no-untyped-def]
    """``'%d.%09d %d %d %d\\n'`` per event into ``out`` (uint8, long enough); t, x, y
    non-negative integers (t ns). Returns the number of bytes written."""
    pairs = _PAIRS
    k = 0
    for j in range(t.shape[0]):
        v = t[j]
        sec = v // 1_000_000_000
        frac = v - sec * 1_000_000_000
        k = _put_int(out, k, sec, pairs)
        out[k] = 46  # '.'
        # nine digits, zero-padded: four pairs and a leading digit
        for e in (k + 9, k + 7, k + 5, k + 3):
            q = frac // 100
            r = frac - q * 100
            out[e - 1] = pairs[r, 0]
            out[e] = pairs[r, 1]
            frac = q
        out[k + 1] = 48 + frac
        out[k + 10] = 32
        k = _put_int(out, k + 11, np.int64(x[j]), pairs)
        out[k] = 32
        k = _put_int(out, k + 1, np.int64(y[j]), pairs)
        out[k] = 32
        out[k + 1] = 49 if p[j] > 0 else 48
        out[k + 2] = 10
        k += 3
    return k
