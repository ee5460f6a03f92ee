"""Amaranth-simulator testbench helpers shared by the block tests."""

__all__ = ["drain"]


async def drain(ctx, port, count, *, rng, prob, convert, limit, out=None):
    """Take ``count`` transfers from the stream ``port`` (its ``ready`` driven, high with
    probability ``prob`` from ``rng``), each payload through ``convert``, into ``out``
    (a list, returned); fails if that takes ``limit`` clocks or more (a hang)."""
    out = [] if out is None else out
    cycles = 0
    while len(out) < count:
        ready = rng.random() < prob
        ctx.set(port.ready, ready)
        *_, valid, payload = await ctx.tick().sample(port.valid, port.payload)
        if valid and ready:
            out.append(convert(payload))
        cycles += 1
        assert cycles < limit, f"{len(out)} of {count} transfers in {limit} clocks: hung"
    return out
