"""The Ray half of test_fleet.py, run by it inside a network namespace of its own with only
loopback (``unshare -rn``; Ray's servers listen on every interface of the host, and with no other
interface Ray takes 127.0.0.1): starts a local Ray cluster of 2 CPUs, runs the fleet job on it
as a library call (the Parquet dataset written to OUT/library) and as ``python -m imud.fleet``
joined to the same cluster (OUT/cli and OUT/fleet.html).

Usage: python3 fleet_on_ray.py RECORDINGS_DIR OUT
"""

import subprocess
import sys
from pathlib import Path

import ray

import imud.fleet

recordings, out = sys.argv[1], Path(sys.argv[2])
ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
try:
    result = imud.fleet.analyze(recordings, engine="ray", latitude_deg=40.0)
    result.write(out / "library")
    cli = subprocess.run(
        [sys.executable, "-m", "imud.fleet", recordings, "--out", str(out / "cli"),
         "--report", str(out / "fleet.html"), "--latitude-deg", "40",
         "--ray-address", ray.get_runtime_context().gcs_address],
        capture_output=True, text=True,
    )
    (out / "cli.stdout").write_text(cli.stdout)
    if cli.returncode != 0:
        sys.exit(f"python -m imud.fleet failed ({cli.returncode}): {cli.stderr}")
finally:
    ray.shutdown()
