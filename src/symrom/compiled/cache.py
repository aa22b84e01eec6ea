"""What numba's disk cache holds (no numba import: the dispatchers asked about bring it)."""

from __future__ import annotations


def in_disk_cache(dispatcher) -> bool:
    """Whether numba's disk cache holds a build of ``dispatcher`` for its present source
    (False where the cache cannot be read)."""
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - numba's cache internals; any failure means "compile"
        return False
