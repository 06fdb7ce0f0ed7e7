"""Calling CasADi functions with numpy arrays, through CasADi's zero-copy buffers.

``fun.call([q])`` is the cheapest plain call (a list of ``DM``) and ``DM.full()`` the
cheapest conversion to numpy; :func:`numpy_function` avoids both and is the fastest way to
evaluate a small function (compiled by `geosyn.core.codegen` or not) once per tick.
"""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca
import numpy as np

from geosyn.core.errors import InvalidArgument

__all__ = ["numpy_function"]


def numpy_function(fun: ca.Function) -> Callable[..., tuple[np.ndarray, ...]]:
    """Wrap a function for fast calls with numpy arrays, through zero-copy buffers.

    Allocates the input and output arrays once; each call copies the arguments in,
    evaluates, and returns the output arrays. The returned arrays are reused by the next
    call: copy them to keep them. Not thread-safe: make one wrapper per thread.

    Args:
        fun: a ``casadi.Function`` with dense inputs and outputs.

    Returns:
        ``call(*args) -> tuple`` of output arrays; an input or output of shape (n, 1) or
        (1, n) is a (n,) array, an (n, m) one an (n, m) array.

    Raises:
        InvalidArgument: ``fun`` has a sparse input or output.
    """
    if not isinstance(fun, ca.Function):
        raise InvalidArgument(f"fun: expected a casadi.Function, got {type(fun).__name__}")

    def shape(sp: ca.Sparsity, what: str) -> tuple[int, ...]:
        if not sp.is_dense():
            raise InvalidArgument(
                f"fun: {what} of {fun.name()!r} is sparse ({sp.nnz()} of {sp.numel()}); "
                "numpy_function needs dense inputs and outputs"
            )
        rows, cols = sp.size1(), sp.size2()
        return (rows * cols,) if 1 in (rows, cols) else (rows, cols)

    in_shapes = [shape(fun.sparsity_in(i), f"input {fun.name_in(i)}") for i in range(fun.n_in())]
    out_shapes = [
        shape(fun.sparsity_out(i), f"output {fun.name_out(i)}") for i in range(fun.n_out())
    ]
    # CasADi stores matrices column-major: flat buffers, seen through Fortran-order views.
    flat_in = [np.zeros(int(np.prod(s))) for s in in_shapes]
    flat_out = [np.zeros(int(np.prod(s))) for s in out_shapes]
    inputs = [f.reshape(s, order="F") for f, s in zip(flat_in, in_shapes, strict=True)]
    outputs = [f.reshape(s, order="F") for f, s in zip(flat_out, out_shapes, strict=True)]
    buffer, evaluate = fun.buffer()
    # CasADi's stub wants (i, buffer, size); the binding takes the size from the buffer
    # (and checks it against the function's nonzeros).
    for i, arr in enumerate(flat_in):
        buffer.set_arg(i, memoryview(arr))  # type: ignore[call-arg, arg-type]
    for i, arr in enumerate(flat_out):
        buffer.set_res(i, memoryview(arr))  # type: ignore[call-arg, arg-type]
    n_in = len(inputs)

    def call(*args: np.ndarray) -> tuple[np.ndarray, ...]:
        if len(args) != n_in:
            raise InvalidArgument(
                f"{fun.name()}: expected {n_in} arguments ({', '.join(fun.name_in())}), "
                f"got {len(args)}"
            )
        for dst, src in zip(inputs, args, strict=True):
            dst[...] = src
        evaluate()
        return tuple(outputs)

    # Keep the buffer alive as long as the callable.
    call.buffer = buffer  # type: ignore[attr-defined]
    return call
