"""Memory intrinsics for numba kernels: ``copy_rows`` (``memcpy``) and ``prefetch_row``.

Numba compiles a slice assignment (``dst[a:b] = src[a:b]``) into an element-by-element
loop, which LLVM does not vectorise over the particles' grids: spans of a few hundred bytes
copied that way run far slower than by ``memcpy``. ``copy_rows`` emits LLVM's ``memcpy``
itself, as NumPy's own copies do.

Comparing a cell across nine particles' grids at resampling waits on nine cache misses, grids
megabytes apart; the hardware prefetcher does not follow such gathers. ``prefetch_row`` asks for
a row some cells ahead (LLVM's ``prefetch``), so that the misses overlap (the caches are cold
at a resampling)."""

from __future__ import annotations

from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic


@intrinsic
def copy_rows(typingctx, dst, src, start, stop):
    """``dst[start:stop] = src[start:stop]`` for C-contiguous arrays of one type that do not overlap there
    (rows of the first axis, whole; the caller keeps ``0 <= start <= stop <= len``: unchecked, as numba's
    indexing is)."""
    if not (isinstance(dst, types.Array) and dst == src and dst.layout == "C" and dst.ndim >= 1 and
            isinstance(start, types.Integer) and isinstance(stop, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        array_type = signature.args[0]
        target = context.make_array(array_type)(context, builder, args[0])
        source = context.make_array(array_type)(context, builder, args[1])
        first = context.cast(builder, args[2], signature.args[2], types.intp)
        last = context.cast(builder, args[3], signature.args[3], types.intp)
        row_bytes = builder.extract_value(target.strides, 0)
        offset = builder.mul(first, row_bytes)
        target_bytes = builder.gep(builder.bitcast(target.data, cgutils.voidptr_t), [offset])
        source_bytes = builder.gep(builder.bitcast(source.data, cgutils.voidptr_t), [offset])
        cgutils.raw_memcpy(builder, target_bytes, source_bytes, builder.mul(builder.sub(last, first), row_bytes), 1)
        return context.get_dummy_value()

    return types.void(dst, src, start, stop), codegen


@intrinsic
def prefetch_row(typingctx, array, index):
    """Ask the cache for row ``index`` of the C-contiguous ``array`` (a hint: it changes no result; the caller
    keeps ``0 <= index < len``)."""
    if not (isinstance(array, types.Array) and array.layout == "C" and array.ndim >= 1 and
            isinstance(index, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        data = context.make_array(signature.args[0])(context, builder, args[0])
        row = context.cast(builder, args[1], signature.args[1], types.intp)
        address = builder.gep(builder.bitcast(data.data, cgutils.voidptr_t),
                              [builder.mul(row, builder.extract_value(data.strides, 0))])
        i32 = ir.IntType(32)
        prefetch = builder.module.declare_intrinsic("llvm.prefetch", [cgutils.voidptr_t],
                                                    ir.FunctionType(ir.VoidType(), [cgutils.voidptr_t, i32, i32, i32]))
        builder.call(prefetch, [address, i32(0), i32(3), i32(1)])  # read, keep in all levels, data
        return context.get_dummy_value()

    return types.void(array, index), codegen
