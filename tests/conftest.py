"""Test configuration: float64 everywhere (as the CLI sets it), compiled programs
released between test modules, and the native kernels' cache located before any test
changes the environment: ``_native`` reads the cache folder once, when first imported,
and a first import inside a test that points XDG_CACHE_HOME at a temporary folder (the
cache-location test) left every later in-process run compiling afresh."""

import jax
import pytest

import beamcontact
import beamcontact._native  # noqa: F401  (its kernel cache is where this process's environment says)

beamcontact.enable_x64()


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's compiled programs after each test module. Every XLA CPU executable
    keeps memory mappings of its own, and the whole suite compiles thousands of them in
    one process: without this it reaches the kernel's limit of 65530 mappings per
    process (vm.max_map_count), and XLA then aborts in whatever it compiles next."""
    yield
    jax.clear_caches()
