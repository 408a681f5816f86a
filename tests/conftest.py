"""Shared pytest fixtures. Never import bpy here: Blender runs only in spawned workers."""

import pytest


@pytest.fixture
def local_ray(monkeypatch):
    """A local Ray instance with 2 CPUs for the test (skipped when ray is not installed)."""
    # Under `uv run pytest`, Ray would start every worker with `uv run` (a re-synced environment per
    # worker; see silpose.datagen.executor.run_ray and silpose.model.streaming.start_ray).
    monkeypatch.setenv("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")
    ray = pytest.importorskip("ray")
    from ray._private import ray_constants

    monkeypatch.setattr(ray_constants, "RAY_ENABLE_UV_RUN_RUNTIME_ENV", False)  # if ray was imported earlier
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()
