"""``hzval sweep``: the truth and every chosen technique over a light sweep, scored, reported and gated.

:func:`hzval.pipeline.sweep.run` does the work.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hzval.commands.gates import Gates
from hzval.metrics.results import SweepResult
from hzval.pipeline import records
from hzval.pipeline import sweep as pipeline_sweep
from hzval.scene.spec import Scene
from hzval.techniques import registry as technique

__all__ = ["selected", "run", "run_line"]


def selected(scene: Scene, options: pipeline_sweep.Options) -> list[str]:
    """Return the names of the techniques a sweep of ``scene`` with ``options`` renders, registry order."""
    requested = None if options.techniques is None else list(options.techniques)
    return [t.name for t in technique.select(requested, scene, exclude=options.exclude)]


def run(
    scene: Scene, out: Path, *, options: pipeline_sweep.Options, gates: Gates | None = None, **kw: Any
) -> dict[str, Any]:
    """Sweep ``scene`` into ``out``; ``metrics.json``'s content.

    Parameters
    ----------
    scene : hzval.scene.spec.Scene
    out : pathlib.Path
        The report's folder.
    options : hzval.pipeline.sweep.Options
    gates : hzval.commands.gates.Gates, optional
        Checked against the techniques and the baseline's settings before anything renders, then
        tested on the result (its ``gates``).
    **kw
        ``command``, ``progress`` and ``force``, as :func:`hzval.pipeline.sweep.run` takes them.
    """
    if gates:
        names = selected(scene, options)
        gates.check_before(names, records.scene_parameters(scene, out, names))
    return pipeline_sweep.run(scene, out, options=options, gates=gates, **kw)


def run_line(result: Mapping[str, Any], out: Path) -> str:
    """Return the line printed under the table.

    It gives the frames, the run's total time (the report's own) and where it went, the peak memory, and where
    the report is.
    """
    t = result["timings"]
    stems = {info["file_stem"] for info in SweepResult.of(result).techniques.values()}
    setup = t.get("plain_setup_s", 0.0) + sum(t.get(f"{s}_setup_s", 0.0) for s in stems)
    parts = [
        f"bake {t['bake_s']:.2f} s{', cached' if t['bake_cached'] else ''}",
        f"truth {t['truth_setup_s'] + t['truth_s']:.2f} s",
        f"techniques {setup + t['technique_frames_s']:.2f} s",  # the renders' wall time
        f"scoring {t.get('compare_s', 0.0):.2f} s",
        f"writing {t.get('write_s', 0.0) + t.get('report_s', 0.0):.2f} s",
    ]
    return (
        f"\n{len(result['frames'])} frames in {t['total_s']:.1f} s ({', '.join(parts)}; peak memory "
        f"{result['memory']['peak_rss_bytes'] / 2**30:.2f} GiB); report: {out / 'index.html'}"
    )
