"""Sweep files: expansion (grid, zip, samples), dotted paths, validation messages."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from roslan.batch import (
    expand_sweep,
    latin_hypercube,
    load_sweep,
    parse_sweep,
    set_dotted,
    sweep_tasks,
)
from roslan.errors import ConfigError

BASE = {
    "trajectory": {
        "k": 0.5,
        "initial": {"position": [-0.4, 0.2, 0.3], "descent_rate": 3.0},
    },
    "sensors": [{"type": "imu", "name": "imu", "rate": 200.0, "topic": "/imu"}],
    "seed": 3,
}


def test_grid_is_cartesian_and_blocks_multiply() -> None:
    sweep = parse_sweep(
        {
            "base": BASE,
            "axes": [
                {"grid": {"trajectory.kappa.x": [0.3, 0.5, 0.7], "seed": [1, 2]}},
                {"grid": {"trajectory.k": {"start": 0.2, "stop": 0.5, "num": 4}}},
            ],
        }
    )
    assert len(sweep.points) == 3 * 2 * 4
    combos = {(p["trajectory.kappa.x"], p["seed"], p["trajectory.k"]) for p in sweep.points}
    assert len(combos) == 24  # every combination exactly once
    ks = sorted({p["trajectory.k"] for p in sweep.points})
    np.testing.assert_allclose(ks, np.linspace(0.2, 0.5, 4))


def test_zip_pairs_elementwise_and_rejects_unequal_lengths() -> None:
    sweep = parse_sweep(
        {
            "base": BASE,
            "axes": [{"zip": {"trajectory.kappa.x": [0.3, 0.5, 0.7], "seed": [7, 8, 9]}}],
        }
    )
    assert [(p["trajectory.kappa.x"], p["seed"]) for p in sweep.points] == [
        (0.3, 7),
        (0.5, 8),
        (0.7, 9),
    ]
    with pytest.raises(ConfigError, match=r"axes\[0\]\.zip.*equal lengths"):
        parse_sweep({"base": BASE, "axes": [{"zip": {"seed": [1, 2], "trajectory.k": [0.5]}}]})


def test_dotted_paths_reach_nested_keys_and_sensors_by_name() -> None:
    cfgs = expand_sweep(
        parse_sweep(
            {
                "base": BASE,
                "axes": [
                    {
                        "zip": {
                            "trajectory.kappa.y": [0.8],
                            "sensors.imu.rate": [500.0],
                            "trajectory.initial.position.2": [0.6],
                            "output.formats": [["ros1"]],
                        }
                    }
                ],
            }
        )
    )
    (cfg,) = cfgs
    assert cfg["trajectory"]["kappa"] == {"y": 0.8}
    assert cfg["sensors"][0]["rate"] == 500.0
    assert cfg["trajectory"]["initial"]["position"] == [-0.4, 0.2, 0.6]
    assert cfg["output"] == {"formats": ["ros1"]}
    # the base itself is untouched
    assert BASE["trajectory"]["initial"]["position"] == [-0.4, 0.2, 0.3]  # type: ignore[index]
    assert "kappa" not in BASE["trajectory"]  # type: ignore[operator]


def test_set_dotted_by_index() -> None:
    cfg = {"sensors": [{"name": "a", "rate": 1.0}, {"name": "b", "rate": 2.0}]}
    set_dotted(cfg, "sensors.1.rate", 9.0)
    set_dotted(cfg, "sensors.a.rate", 4.0)
    assert [s["rate"] for s in cfg["sensors"]] == [4.0, 9.0]


@pytest.mark.parametrize(
    ("key", "expect"),
    [
        ("trajectory.kapa.x", r"'kapa' is not a key of trajectory; allowed: .*kappa"),
        ("trajectory.kappa.z", r"'z' is not a key of trajectory\.kappa; allowed: x, y, roll"),
        ("sensors.gyro.rate", r"no sensor named 'gyro'.*allowed: 'imu'"),
        ("sensors.imu.noise", r"'noise' is not a key of sensors\.imu"),
        ("seed.value", r"seed is a value"),
        ("outputs", r"'outputs' is not a key of the config root"),
        ("trajectory.goal.position.5", r"index 5 needs trajectory\.goal\.position"),
    ],
)
def test_bad_dotted_path_is_a_clear_error(tmp_path: Path, key: str, expect: str) -> None:
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({"base": BASE, "axes": [{"grid": {key: [1]}}]}))
    with pytest.raises(ConfigError, match=expect) as info:
        load_sweep(sweep)
    assert str(sweep) in str(info.value)
    assert key in str(info.value)


def test_lhs_is_in_bounds_stratified_and_seeded() -> None:
    spec = {
        "base": BASE,
        "axes": [
            {
                "sample": {
                    "n": 16,
                    "method": "lhs",
                    "seed": 5,
                    "ranges": {
                        "trajectory.kappa.x": [0.2, 0.9],
                        "seed": [0, 15],
                        "sensors.imu.rate": {"low": 100.0, "high": 1000.0, "log": True},
                        "scene": {"choices": ["warehouse", "refinery"]},
                    },
                }
            }
        ],
    }
    pts = parse_sweep(spec).points
    kx = np.array([p["trajectory.kappa.x"] for p in pts])
    assert np.all((kx >= 0.2) & (kx < 0.9))
    # Latin hypercube: exactly one sample in each of the 16 equal strata of every axis
    strata = np.floor((kx - 0.2) / 0.7 * 16).astype(int)
    assert sorted(strata) == list(range(16))
    seeds = [p["seed"] for p in pts]
    assert sorted(seeds) == list(range(16))  # 16 integers in [0, 15], one per stratum
    assert all(isinstance(s, int) for s in seeds)
    rates = np.array([p["sensors.imu.rate"] for p in pts])
    log_strata = np.floor((np.log(rates) - math.log(100)) / math.log(10) * 16).astype(int)
    assert sorted(log_strata) == list(range(16))
    scenes = [p["scene"] for p in pts]
    assert scenes.count("warehouse") == scenes.count("refinery") == 8
    # same seed -> same samples; another seed -> different ones
    assert parse_sweep(spec).points == pts
    spec["axes"][0]["sample"]["seed"] = 6  # type: ignore[index]
    assert parse_sweep(spec).points != pts


def test_latin_hypercube_unit_strata() -> None:
    u = latin_hypercube(50, 3, seed=1)
    assert u.shape == (50, 3)
    for j in range(3):
        assert sorted(np.floor(u[:, j] * 50).astype(int)) == list(range(50))


def test_random_sampling_is_seeded_and_in_bounds() -> None:
    spec = {
        "axes": [
            {
                "sample": {
                    "n": 40,
                    "method": "random",
                    "seed": 2,
                    "ranges": {"trajectory.k": [0.1, 0.5]},
                }
            }
        ]
    }
    a = [p["trajectory.k"] for p in parse_sweep(spec).points]
    assert a == [p["trajectory.k"] for p in parse_sweep(spec).points]
    assert all(0.1 <= v < 0.5 for v in a)
    assert len(set(a)) == 40


def test_base_from_a_file_and_relative_paths(tmp_path: Path) -> None:
    (tmp_path / "cfg").mkdir()
    (tmp_path / "cfg" / "base.yaml").write_text(yaml.safe_dump(BASE))
    (tmp_path / "sweep.yaml").write_text(
        yaml.safe_dump({"base": "cfg/base.yaml", "axes": [{"grid": {"seed": [1, 2]}}]})
    )
    sweep = load_sweep(tmp_path / "sweep.yaml")
    assert sweep.base_dir == (tmp_path / "cfg").resolve()
    assert sweep.config_file == (tmp_path / "cfg" / "base.yaml").resolve()
    assert [c["seed"] for c in expand_sweep(sweep)] == [1, 2]


@pytest.mark.parametrize(
    ("data", "expect"),
    [
        ({"axes": [{"grid": {"seed": []}}]}, r"axes\[0\]\.grid\.seed = \[\]: a non-empty list"),
        ({"axes": [{"grid": {}, "zip": {}}]}, r"axes\[0\].*exactly one of: grid, zip, sample"),
        ({"axes": [{"sample": {"n": 0, "ranges": {"seed": [0, 1]}}}]}, r"sample\.n = 0"),
        (
            {"axes": [{"sample": {"n": 2, "method": "sobol", "ranges": {"seed": [0, 1]}}}]},
            r"method = 'sobol': allowed: lhs, random",
        ),
        (
            {"axes": [{"sample": {"n": 2, "ranges": {"trajectory.k": [0.5, 0.1]}}}]},
            r"ranges\.trajectory\.k.*low < high",
        ),
        ({"bases": {}}, r"bases = .*unknown key; allowed: base, axes, name"),
        (
            {"axes": [{"grid": {"seed": [1]}}, {"zip": {"seed": [2]}}]},
            r"axes\[1\].*already varied by axes\[0\]",
        ),
        ({"name": "{scene}"}, r"name = '\{scene\}'"),
        (
            {"axes": [{"sample": {"n": 100_001, "ranges": {"seed": [0, 1]}}}]},
            r"sample\.n = 100001: an integer in \[1, 100000\]",
        ),
        (
            {
                "axes": [
                    {"grid": {"seed": list(range(400))}},
                    {"grid": {"trajectory.k": [0.3 + 1e-4 * i for i in range(400)]}},
                ]
            },
            r"axes = '160000 tasks': a sweep has at most 100000 tasks",
        ),
    ],
)
def test_sweep_file_errors_name_key_value_allowed(
    tmp_path: Path, data: dict[str, object], expect: str
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, **data}))
    with pytest.raises(ConfigError, match=expect) as info:
        load_sweep(path)
    assert str(path) in str(info.value)


def test_invalid_configs_are_reported_per_task() -> None:
    sweep = parse_sweep(
        {
            "base": BASE,
            "axes": [
                {"grid": {"trajectory.kappa.x": [0.5, 5.0, 2.5], "sensors.imu.rate": [100.0, -1.0]}}
            ],
        }
    )
    tasks = sweep_tasks(sweep)
    assert len(tasks) == 6
    bad = {t.name: t.error for t in tasks if t.error}
    good = [t for t in tasks if not t.error]
    # kappa.x = 5 or 2.5 makes k*kappa > 1 (invalid); rate -1 is invalid
    assert len(good) == 1
    assert good[0].overrides == {"trajectory.kappa.x": 0.5, "sensors.imu.rate": 100.0}
    assert len(bad) == 5
    for t in tasks:
        if t.error and t.overrides["sensors.imu.rate"] == -1.0:
            assert "sensors[0].rate = -1.0" in t.error
        elif t.error:
            assert "kappa" in t.error
    assert len({t.fingerprint for t in good}) == 1
    assert good[0].fingerprint
