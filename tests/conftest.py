"""Test configuration: float64 everywhere (as the CLI sets it), and compiled programs
released between test modules."""

import jax
import pytest

import beamcontact

beamcontact.enable_x64()


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's compiled programs after each test module. Every XLA CPU executable
    keeps memory mappings of its own, and the whole suite compiles thousands of them in
    one process: without this it reaches the kernel's limit of 65530 mappings per
    process (vm.max_map_count), and XLA then aborts in whatever it compiles next."""
    yield
    jax.clear_caches()
