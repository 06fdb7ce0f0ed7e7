"""The hand-written C backward pass of the box-DDP solver (``geosyn_ddp.c``, package data)
and the small generated functions it calls; geosyn's Python solver runs it through
`native_backward` and `geosyn.export` copies the same C files into an export."""

from geosyn.controllers.mpc.ddp.native.library import (
    C_DIR,
    compile_flags,
    native_backward,
    native_source,
)

__all__ = ["C_DIR", "compile_flags", "native_backward", "native_source"]
