"""How the native kernels are compiled (beamcontact/_native.py, beamcontact/_warmup.py;
docs/engines.md, "Compilation"): a constant argument compiles no second kernel, a kernel
compiled inside another keeps IEEE arithmetic, and the helper that compiles the time
loop builds its model with the spline kernels run as Python, to the same numbers.

Each check runs in a fresh process with the kernel cache off, so that what it counts is
compiled there and then."""

import os
import subprocess
import sys

import jax
import numpy as np

from beamcontact import _warmup
from beamcontact.io.case import parse_case
from beamcontact.setup.start import prepare


def _python(code: str, cache: str = "") -> str:
    env = {**os.environ, "BEAMCONTACT_CACHE_DIR": cache}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


_KERNELS = '''
import numpy as np
from beamcontact import _native

@_native.njit
def scaled(x, twice):
    return 2.0 * x if twice else x

@_native.njit
def with_constant(x):
    return scaled(x, False) + scaled(x, True)

@_native.njit
def with_variable(x, twice):
    return scaled(x, twice)

@_native.njit
def terms(x):
    # a sum whose value depends on the order of its terms and a product-sum that a
    # fused multiply-add would round once instead of twice
    s = 0.0
    for i in range(x.shape[0]):
        s += x[i] * x[x.shape[0] - 1 - i] + 1e-17 * i
    return s

@_native.njit
def outer(x):
    return terms(x)
'''


def test_a_constant_argument_compiles_the_kernel_once():
    """``scaled`` called with the constants False and True and with a variable: one
    compiled version (bool), not one per constant (_native._typed_without_constants)."""
    out = _python(_KERNELS + "print(with_constant(3.0), with_variable(3.0, True), "
                  "with_variable(3.0, False), len(scaled.signatures), scaled.signatures)")
    a, b, c, count, _ = out.split(maxsplit=4)
    assert (float(a), float(b), float(c)) == (9.0, 6.0, 3.0)
    assert int(count) == 1, out


def test_a_kernel_compiled_inside_another_computes_as_python():
    """``terms`` compiled first inside ``outer`` (its library then skips LLVM's module
    passes, _native._optimise_outermost_only) and then called from Python: both give
    Python's float64 result bit for bit, so no pass reordered or fused the arithmetic."""
    out = _python(_KERNELS + '''
rng = np.random.default_rng(3)
x = rng.standard_normal(257) * 10.0 ** rng.integers(-8, 8, 257)
print(_native.OPTIMISE_OUTERMOST_ONLY, outer(x).hex(), terms(x).hex(), terms.py_func(x).hex())
''')
    hooked, via_outer, direct, python = out.split()
    assert hooked == "True"  # with the Numba this package supports, the hook is in place
    assert via_outer == direct == python


# the helper's model, built in a process whose spline kernels run as Python, into the
# file argv[1]
_HELPER_MODEL = '''
import numpy as np, sys
from beamcontact import _warmup
_warmup._splines_in_python()
from beamcontact.io.case import parse_case
from beamcontact.setup.start import prepare
kernels = [m.__name__ + "." + k for m in list(sys.modules.values())
           if getattr(m, "__name__", "").startswith("beamcontact.")
           for k, v in vars(m).items() if hasattr(v, "py_func")
           and getattr(v, "__module__", "").startswith("beamcontact.spline.")]
import jax
from beamcontact import enable_x64
enable_x64()
p = prepare(parse_case(_warmup.TINY_CASE))
leaves = jax.tree_util.tree_leaves((p.model, p.contact.elements))
np.savez(sys.argv[1], *[np.asarray(v) for v in leaves], kernels=np.array(kernels, dtype=str))
'''


def test_the_helper_builds_its_model_with_python_splines(tmp_path):
    """The helper (_warmup._splines_in_python) leaves no spline kernel bound to a name in
    the package, and every array of its model (control points, basis functions at the
    quadrature and contact points) is that of the compiled kernels, bit for bit."""
    path = tmp_path / "helper.npz"
    env = {**os.environ, "BEAMCONTACT_CACHE_DIR": ""}
    out = subprocess.run([sys.executable, "-c", _HELPER_MODEL, str(path)], env=env,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    helper = np.load(path)
    assert list(helper["kernels"]) == []
    p = prepare(parse_case(_warmup.TINY_CASE))
    leaves = jax.tree_util.tree_leaves((p.model, p.contact.elements))
    assert len(leaves) == len(helper.files) - 1
    for k, leaf in enumerate(leaves):
        np.testing.assert_array_equal(helper[f"arr_{k}"], np.asarray(leaf))
