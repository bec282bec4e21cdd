"""Where the per-recording jobs run: on Ray (one task per recording) or in-process.

Ray: each recording is one ``ray.remote(num_cpus=1)`` task running
:func:`imud.fleet.job.analyze_recording`; the rows are gathered in input order. The job joins
the cluster at ``ray_address`` (``"auto"``, ``ray://HOST:PORT``), uses the one this process
already joined (``ray.init`` called before, e.g. inside a Ray job), or else starts a local
instance and stops it after. ``local`` runs the same function in a plain loop.
"""

from __future__ import annotations

from typing import Any, Dict, List, Optional, Sequence

from .inputs import RecordingSpec
from .job import JobOptions, analyze_recording

ENGINES = ("ray", "local")


def run(
    specs: Sequence[RecordingSpec],
    options: JobOptions,
    engine: str = "ray",
    ray_address: Optional[str] = None,
) -> List[Dict[str, Any]]:
    """One row per recording, in the order of ``specs``."""
    if engine == "local":
        return [analyze_recording(s, options) for s in specs]
    if engine != "ray":
        raise ValueError(f"engine {engine!r}: use one of {', '.join(ENGINES)}")
    return _run_ray(specs, options, ray_address)


def _run_ray(
    specs: Sequence[RecordingSpec], options: JobOptions, ray_address: Optional[str]
) -> List[Dict[str, Any]]:
    try:
        import ray
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(
            "engine='ray' needs Ray: pip install 'imud[fleet]' (or run with engine='local')"
        ) from e
    started = False
    if not ray.is_initialized():
        if ray_address is None:
            # A private local instance: no dashboard (it only slows the start).
            ray.init(include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=ray_address, log_to_driver=False)
        started = True
    try:
        task = ray.remote(num_cpus=1)(analyze_recording)
        opts = ray.put(options)
        refs = [task.remote(s, opts) for s in specs]
        rows = []
        for spec, ref in zip(specs, refs):
            try:
                rows.append(ray.get(ref))
            except Exception as e:  # noqa: BLE001 - a lost worker is that recording's error
                rows.append({"path": spec.path, "error": f"the Ray task failed: {e}"})
        return rows
    finally:
        if started:
            ray.shutdown()
