"""``roslan scene export|info|preview NAME_OR_FILE``."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from roslan.cli.common import seed_arg

__all__ = ["register"]


def _load(args: argparse.Namespace) -> Any:
    from roslan.scene import load_scene

    return load_scene(args.scene, seed=args.seed, allow_external_paths=args.allow_external_paths)


def _export(args: argparse.Namespace) -> int:
    from roslan.scene import export_scene

    scene = _load(args)
    export_scene(scene, Path(args.output))
    print(f"wrote {len(scene.objects)} models, poses.yaml and scene.yaml to {args.output}")
    return 0


def _info(args: argparse.Namespace) -> int:
    if args.json:
        import json

        from roslan.scene.instances import labels_document

        print(json.dumps(labels_document(_load(args)), indent=1))
        return 0
    from roslan.plots.scene import scene_info

    print(scene_info(_load(args)))
    return 0


def _preview(args: argparse.Namespace) -> int:
    from roslan.plots.scene import write_preview

    write_preview(_load(args), Path(args.output), rendered=not args.top_only)
    print(f"wrote {args.output}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``roslan scene ...`` to the top-level parser."""
    p = subparsers.add_parser("scene", help="inspect, preview and export scenes")
    sub = p.add_subparsers(dest="scene_command", metavar="SUBCOMMAND")

    def common(sp: argparse.ArgumentParser) -> None:
        sp.add_argument(
            "scene", metavar="NAME_OR_FILE", help="warehouse, refinery, empty or a scene YAML"
        )
        sp.add_argument(
            "--seed", type=seed_arg, default=0, help="seed of the procedural parts (default 0)"
        )
        sp.add_argument(
            "--allow-external-paths",
            action="store_true",
            help="let the scene file use absolute paths or paths outside its folder",
        )

    e = sub.add_parser("export", help="GLB per object, poses.yaml and a reloadable scene.yaml")
    common(e)
    e.add_argument("-o", "--output", required=True, metavar="DIR", help="new (or empty) folder")
    e.set_defaults(func=_export)
    i = sub.add_parser("info", help="objects, triangles, bounds, goal, classes and instances")
    common(i)
    i.add_argument(
        "--json",
        action="store_true",
        help="print the classes and instances (with their 3-D boxes) as JSON instead",
    )
    i.set_defaults(func=_info)
    v = sub.add_parser(
        "preview", help="PNG: top view with outlines and the goal, and two rendered views"
    )
    common(v)
    v.add_argument("-o", "--output", required=True, metavar="FILE.png", help="PNG to write")
    v.add_argument(
        "--top-only", action="store_true", help="the top view alone (no OpenGL rendering)"
    )
    v.set_defaults(func=_preview)
    p.set_defaults(func=lambda _args: (p.print_help(), 2)[1])
