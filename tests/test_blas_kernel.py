"""OpenBLAS's kernel pinned before NumPy loads, so that the simulated data's bits do not depend
on the CPU's vector width (``symrom.execution.pin_blas_kernel``)."""

import os
import platform
import subprocess
import sys

import pytest

from symrom.execution import BLAS_KERNEL, BLAS_KERNEL_ENV, pin_blas_kernel

linux_x86 = pytest.mark.skipif(sys.platform != "linux" or platform.machine() != "x86_64",
                               reason="the kernel is pinned on Linux x86-64 only")


def _fresh(code: str, **env: str) -> str:
    """``code`` run in a new Python without ``OPENBLAS_CORETYPE`` (unless ``env`` sets it)."""
    base = {k: v for k, v in os.environ.items() if k != BLAS_KERNEL_ENV}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**base, **env},
                         timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_the_environments_kernel_wins_and_a_loaded_numpy_is_left_alone():
    env = {BLAS_KERNEL_ENV: "Zen"}
    assert pin_blas_kernel(env) == "Zen" and env == {BLAS_KERNEL_ENV: "Zen"}
    env = {}
    assert "numpy" in sys.modules  # loaded by the tests: too late to pin, so nothing is set
    assert pin_blas_kernel(env) is None and env == {}


@linux_x86
def test_pinned_only_where_the_cpu_runs_the_kernel(tmp_path):
    with_avx2 = tmp_path / "with"
    with_avx2.write_text("processor\t: 0\nflags\t\t: fpu sse2 avx fma avx2 bmi2\n")
    without = tmp_path / "without"
    without.write_text("processor\t: 0\nflags\t\t: fpu sse2 avx\n")
    code = ("from symrom.execution import pin_blas_kernel; import sys; "
            f"e = {{}}; print(pin_blas_kernel(e, cpuinfo={str(with_avx2)!r}), e.get({BLAS_KERNEL_ENV!r})); "
            f"e = {{}}; print(pin_blas_kernel(e, cpuinfo={str(without)!r}), e); "
            "assert 'numpy' not in sys.modules")
    assert _fresh(code).splitlines() == [f"{BLAS_KERNEL} {BLAS_KERNEL}", "None {}"]


@linux_x86
def test_numpy_then_runs_the_pinned_kernel():
    code = ("from symrom.execution import blas_kernels, pin_blas_kernel; kernel = pin_blas_kernel(); "
            "import numpy; print(kernel); print(*blas_kernels(), sep='\\n')")
    kernel, *loaded = _fresh(code).splitlines()
    if kernel == "None":
        pytest.skip("this CPU has no AVX2 and FMA: OpenBLAS keeps its own choice")
    assert kernel == BLAS_KERNEL and loaded and all(line.endswith(f"({BLAS_KERNEL})") for line in loaded)
    assert _fresh(code, **{BLAS_KERNEL_ENV: "Sandybridge"}).splitlines()[0] == "Sandybridge"
