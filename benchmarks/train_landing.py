"""PPO learns the vertical channel of a ``roslan/LandingLite-v0`` landing from events.

Needs the ``rl`` extra (``pip install 'roslan[rl]'``: stable-baselines3, torch).

What the agent sees and flies (docs/guide/closed-loop.md, "Learning a landing from events"):

* **Input:** the observation only (:func:`features`): the step's event count image
  (2 x 48 x 64) sum-pooled 4 x 4 to 2 x 12 x 16 and ``log1p``-compressed, the step's IMU
  samples reduced to their mean specific force and body rates, ``time``, the constant
  ``start_estimate`` and ``goal`` entries, and the agent's own last action.
* **Action:** ``az`` only, as a residual: the vertical acceleration flown is the
  ``tau-events`` controller's (:class:`roslan.env.tau_events.TauEventsPolicy`, from the
  IMU and the raw events, never the truth) plus ``RESIDUAL_SCALE * a``, ``a`` in [-1, 1].
  The five other components (``ax, ay`` and the body rates) are ``tau-events``' as well.
* **Truth:** never read. :class:`EventsVertical` hands the controller and the caller an
  ``info`` (:class:`NoTruthInfo`) whose ``"state"`` raises :class:`TruthAccess`; the
  learning curve and the evaluation read only the episode's outcome (the env's
  ``info["episode"]``, moved to ``info["landing"]``: stable-baselines3 owns ``"episode"``):
  success and touchdown speeds.

Seeds: training episodes use seeds ``seed * 1_000_000 + n_envs * k + i``, ..., held-out
evaluation seeds ``EVAL_SEED_BASE + 0..19`` (disjoint). torch runs one thread per process.

    python benchmarks/train_landing.py --total-steps 60000 --n-envs 4 --seed 0 -o out_train
    python benchmarks/train_landing.py --plot out_train/curve.csv \
        --figure docs/img/learning_curve.png

Writes ``OUT/curve.csv`` (learning curve), ``OUT/model.zip`` and ``OUT/eval.json``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import sys
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

EVAL_SEED_BASE = 900_000
"""Held-out evaluation seeds: ``EVAL_SEED_BASE + 0..19`` (training seeds are below it)."""
RESIDUAL_SCALE = 3.0
"""m/s^2 of vertical acceleration per unit of the agent's action."""
POOL = 4
"""Event image sum-pooling factor (64 x 48 -> 16 x 12)."""
CURVE_FIELDS = (
    "env_steps",
    "wall_s",
    "cpu_s",
    "episodes",
    "success_rate",
    "mean_touchdown_vertical_speed",
    "mean_touchdown_horizontal_speed",
)


class TruthAccess(RuntimeError):
    """Raised when code reads ``info["state"]`` (the true state) on the learning path."""


class NoTruthInfo(dict[str, Any]):
    """A step's ``info`` without the true state: reading ``"state"`` raises."""

    def __init__(self, info: Mapping[str, Any]) -> None:
        super().__init__((k, v) for k, v in info.items() if k != "state")

    def __getitem__(self, key: str) -> Any:
        if key == "state":
            raise TruthAccess("info['state'] (the true state) read on the learning path")
        return super().__getitem__(key)

    def get(self, key: str, default: Any = None) -> Any:
        if key == "state":
            raise TruthAccess("info['state'] (the true state) read on the learning path")
        return super().get(key, default)

    def __contains__(self, key: object) -> bool:
        if key == "state":
            raise TruthAccess("info['state'] (the true state) probed on the learning path")
        return super().__contains__(key)


def pooled_events(count: np.ndarray) -> np.ndarray:
    """(2, H, W) counts -> (2, H / POOL, W / POOL) sums, ``log1p``-compressed."""
    c, h, w = count.shape
    s = count.reshape(c, h // POOL, POOL, w // POOL, POOL).sum(axis=(2, 4))
    return np.log1p(s).astype(np.float32)


def imu_summary(rows: np.ndarray) -> np.ndarray:
    """The step's mean specific force (m/s^2, /10) and body rates (rad/s) (6,)."""
    valid = rows[:, 0] > 0.5
    if not valid.any():
        return np.zeros(6, dtype=np.float32)
    m = rows[valid, 2:8].mean(axis=0)
    m[:3] /= 10.0
    return m.astype(np.float32)


def features(obs: Mapping[str, Any], last_action: float) -> np.ndarray:
    """The agent's input vector from the observation alone (module docstring)."""
    return np.concatenate(
        [
            pooled_events(np.asarray(obs["events"], dtype=np.float32)).ravel(),
            imu_summary(np.asarray(obs["imu"], dtype=np.float32)),
            np.asarray(obs["time"], dtype=np.float32) / 10.0,
            np.asarray(obs["start_estimate"], dtype=np.float32) / 10.0,
            np.asarray(obs["goal"], dtype=np.float32) / 10.0,
            np.array([last_action], dtype=np.float32),
        ]
    )


class EventsVertical(gym.Wrapper[Any, Any, Any, Any]):
    """``LandingLite-v0`` with a residual ``az`` action on top of ``tau-events`` and a
    flat feature observation (module docstring); ``info`` never carries the truth."""

    def __init__(self, env: gym.Env[Any, Any], residual_scale: float = RESIDUAL_SCALE) -> None:
        super().__init__(env)
        from roslan.env.tau_events import TauEventsPolicy

        self.scale = float(residual_scale)
        self._policy = TauEventsPolicy()
        self.action_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        n = features(env.observation_space.sample(), 0.0).shape[0]
        self.observation_space = spaces.Box(-np.inf, np.inf, (n,), dtype=np.float32)
        self._obs: Any = None
        self._info: NoTruthInfo = NoTruthInfo({})
        self._last = 0.0
        self._bound = float(env.action_space.high[2])  # type: ignore[attr-defined]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, NoTruthInfo]:
        obs, info = self.env.reset(seed=seed, options=options)
        self._policy.reset(self.env.unwrapped.policy_context())  # type: ignore[attr-defined]
        self._obs, self._info, self._last = obs, NoTruthInfo(info), 0.0
        return features(obs, 0.0), self._info

    def full_action(self, action: Any) -> np.ndarray:
        """The six values flown: ``tau-events``' with ``az += scale * a``."""
        a = float(np.clip(np.asarray(action, dtype=np.float64).reshape(-1)[0], -1.0, 1.0))
        full = np.asarray(self._policy.act(self._obs, self._info), dtype=np.float64).copy()
        full[2] = np.clip(full[2] + self.scale * a, -self._bound, self._bound)
        # the controller's strapdown model of the commanded acceleration follows what flew
        self._policy._a_cmd = full[:3].copy()
        self._last = a
        return full

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, NoTruthInfo]:
        full = self.full_action(action)
        obs, reward, terminated, truncated, info = self.env.step(full)
        self._obs, self._info = obs, NoTruthInfo(info)
        self._info["action"] = full
        if dict.__contains__(self._info, "episode"):  # stable-baselines3 owns "episode"
            self._info["landing"] = dict.pop(self._info, "episode")
        return features(obs, self._last), float(reward), terminated, truncated, self._info


def make_env(rank: int = 0) -> gym.Env[Any, Any]:
    """One wrapped ``LandingLite-v0`` (imports roslan.env: registers the id)."""
    import roslan.env  # noqa: F401

    del rank
    return EventsVertical(gym.make("roslan/LandingLite-v0"))


def cpu_seconds() -> float:
    """CPU seconds of this process and its waited-for children (threads included)."""
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def evaluate(model: Any, seeds: list[int]) -> dict[str, Any]:
    """Deterministic episodes of ``model`` on ``seeds``: outcomes from ``info["landing"]``."""
    env = make_env()
    rows = []
    try:
        for s in seeds:
            obs, _ = env.reset(seed=s)
            done = False
            while not done:
                a, _ = model.predict(obs, deterministic=True)
                obs, _, te, tr, info = env.step(a)
                done = te or tr
            ep = dict.__getitem__(info, "landing")
            rows.append({k: ep.get(k) for k in _EP_KEYS})
    finally:
        env.close()
    ok = [bool(r["success"]) for r in rows]
    return {"seeds": seeds, "success_rate": float(np.mean(ok)), "episodes": rows}


_EP_KEYS = (
    "seed",
    "success",
    "reason",
    "steps",
    "touchdown_vertical_speed",
    "touchdown_horizontal_speed",
    "position_error",
)


def _episode_ends(infos: list[Any], dones: np.ndarray) -> Iterator[Mapping[str, Any]]:
    for info, d in zip(infos, dones, strict=True):
        ep = dict.get(info, "landing") if d else None
        if isinstance(ep, Mapping) and "success" in ep:
            yield ep


def _curve_callback(path: Path, every: int, t0: tuple[float, float]) -> Any:
    from stable_baselines3.common.callbacks import BaseCallback

    class Curve(BaseCallback):
        """Appends a learning-curve row every ``every`` env steps (episodes since the last)."""

        def _on_training_start(self) -> None:
            self.rows: list[dict[str, Any]] = []
            self.window: list[Mapping[str, Any]] = []
            self.episodes = 0
            self.next = every

        def _on_step(self) -> bool:
            eps = list(_episode_ends(self.locals["infos"], self.locals["dones"]))
            self.window += eps
            self.episodes += len(eps)
            if self.num_timesteps >= self.next:
                self.next += every
                self._row()
            return True

        def _on_training_end(self) -> None:
            if self.window:
                self._row()

        def _row(self) -> None:
            w = self.window
            vz = [float(e["touchdown_vertical_speed"] or np.nan) for e in w]
            vh = [float(e["touchdown_horizontal_speed"] or np.nan) for e in w]
            self.rows.append(
                {
                    "env_steps": self.num_timesteps,
                    "wall_s": round(time.perf_counter() - t0[0], 2),
                    "cpu_s": round(cpu_seconds() - t0[1], 2),
                    "episodes": self.episodes,
                    "success_rate": float(np.mean([bool(e["success"]) for e in w])) if w else "",
                    "mean_touchdown_vertical_speed": float(np.nanmean(vz)) if w else "",
                    "mean_touchdown_horizontal_speed": float(np.nanmean(vh)) if w else "",
                }
            )
            self.window = []
            lines = [",".join(CURVE_FIELDS)]
            lines += [",".join(str(r[k]) for k in CURVE_FIELDS) for r in self.rows]
            _atomic_write(path, "\n".join(lines) + "\n")
            print(lines[-1], flush=True)

    return Curve()


def train(args: argparse.Namespace) -> dict[str, Any]:
    """PPO on ``n_envs`` wrapped envs in one process; the curve, model and evaluation."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    t0 = (time.perf_counter(), cpu_seconds())
    venv = DummyVecEnv([lambda i=i: make_env(i) for i in range(args.n_envs)])
    venv.seed(args.seed * 1_000_000)
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=args.n_steps,
        batch_size=args.batch_size,
        n_epochs=5,
        learning_rate=3e-4,
        gamma=0.995,
        ent_coef=0.0,
        policy_kwargs={"net_arch": [64, 64]},
        seed=args.seed,
        device="cpu",
        verbose=0,
    )
    every = args.n_steps * args.n_envs
    model.learn(args.total_steps, callback=_curve_callback(out / "curve.csv", every, t0))
    venv.close()
    train_wall, train_cpu = time.perf_counter() - t0[0], cpu_seconds() - t0[1]
    model.save(out / "model.zip")
    ev = evaluate(model, [EVAL_SEED_BASE + i for i in range(args.eval_episodes)])
    result = {
        "env_steps": int(model.num_timesteps),
        "n_envs": args.n_envs,
        "seed": args.seed,
        "train_wall_hours": train_wall / 3600.0,
        "train_cpu_hours": train_cpu / 3600.0,
        "total_wall_hours": (time.perf_counter() - t0[0]) / 3600.0,
        "total_cpu_hours": (cpu_seconds() - t0[1]) / 3600.0,
        "load_average": os.getloadavg(),
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "evaluation": ev,
    }
    _atomic_write(out / "eval.json", json.dumps(result, indent=1) + "\n")
    return result


def plot(curve: Path, figure: Path, eval_json: Path | None = None) -> None:
    """The learning curve: success rate and mean touchdown speed against env steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with curve.open() as f:
        rows = [r for r in csv.DictReader(f) if r["success_rate"] != ""]
    x = np.array([int(r["env_steps"]) for r in rows])
    fig, ax = plt.subplots(1, 2, figsize=(8, 3), dpi=90)
    ax[0].plot(x, [float(r["success_rate"]) for r in rows], "o-", ms=3)
    ax[0].set(xlabel="env steps", ylabel="training success rate", ylim=(-0.05, 1.05))
    ax[0].axhline(0.8, color="gray", ls="--", lw=0.8)
    ax[1].plot(x, [float(r["mean_touchdown_vertical_speed"]) for r in rows], "o-", ms=3,
               label="vertical")  # fmt: skip
    ax[1].plot(x, [float(r["mean_touchdown_horizontal_speed"]) for r in rows], "s-", ms=3,
               label="horizontal")  # fmt: skip
    ax[1].axhline(0.5, color="gray", ls="--", lw=0.8)
    ax[1].set(xlabel="env steps", ylabel="mean touchdown speed, m/s")
    ax[1].legend(fontsize=8)
    title = "PPO, az residual on tau-events, LandingLite-v0"
    if eval_json is not None and eval_json.exists():
        ev = json.loads(eval_json.read_text())
        title += f" | held-out success {ev['evaluation']['success_rate']:.0%}"
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    figure.parent.mkdir(parents=True, exist_ok=True)
    tmp = figure.with_name(figure.stem + ".tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, figure)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--total-steps", type=int, default=60_000)
    p.add_argument("--n-envs", type=int, default=4)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("-o", "--output", default="out_train")
    p.add_argument("--n-steps", type=int, default=256, help="PPO rollout per env")
    p.add_argument("--batch-size", type=int, default=256)
    p.add_argument("--eval-episodes", type=int, default=20)
    p.add_argument("--plot", type=Path, help="only plot this curve.csv")
    p.add_argument("--figure", type=Path, default=Path("docs/img/learning_curve.png"))
    args = p.parse_args(argv)
    if args.plot is not None:
        plot(args.plot, args.figure, args.plot.with_name("eval.json"))
        return 0
    res = train(args)
    ev = res["evaluation"]
    print(json.dumps({k: v for k, v in res.items() if k != "evaluation"}))
    print(f"held-out success: {ev['success_rate']:.0%} on {len(ev['seeds'])} seeds")
    plot(Path(args.output) / "curve.csv", args.figure, Path(args.output) / "eval.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
