"""AXI4-Lite register file generated from a register map (:mod:`hdl.bus.register_map`):
one port per register, so a block adds a register by adding a line to its group in
:mod:`hdl.bus.regmap`, with no decoder changes."""

from amaranth.hdl import Cat, Const, Module, Mux, Signal, Value
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from hdl.bus.axi4lite import RESP_OKAY, RESP_SLVERR, AXI4LiteSignature
from hdl.bus.register_map import WORD_BYTES, Access, RegisterMap

__all__ = ["RegisterFile", "command_signature"]


def command_signature(shape, count=1):
    """The port of a write-only register as the register file drives it: the written
    value and a strobe per array element, high for one clock after the write. A block
    that takes the command declares ``In(command_signature(...))``."""
    return wiring.Signature({"data": Out(shape), "stb": Out(count)})


class RegisterFile(wiring.Component):
    """AXI4-Lite slave that decodes a :class:`RegisterMap` into one port per register.

    Parameters
    ----------
    regmap : RegisterMap
    addr_width : int
        Width of the bus address; addresses outside ``[base, base + size)`` answer
        SLVERR.

    Members
    -------
    axi : In(AXI4LiteSignature(addr_width))
    <group> : Out(Signature)
        One member per group, and in it one per register: ``rw`` → ``Out(shape)`` (the
        stored value), ``ro`` → ``In(shape)`` (sampled the clock after the read address
        is taken; an element of several words is sampled whole when its word 0 is
        read, and its other words answer from that sample), ``wo`` →
        ``Out(Signature(data: shape, stb: count))`` (``stb[k]`` high for one clock when
        element ``k`` was written), ``const`` → no port. ``shape`` is
        the register's shape, or an ``ArrayLayout`` of it when ``count > 1``.

    Latency: a read answers two clocks after its address is taken; a write is accepted
    when address and data are both valid and answers the next clock. One read and one
    write can be in flight at once. Reset: ``rw`` registers return to their reset
    values.
    """

    def __init__(self, regmap, *, addr_width=32):
        if not isinstance(regmap, RegisterMap):
            raise TypeError(f"regmap must be a RegisterMap, not {regmap!r}")
        if not isinstance(addr_width, int) or not regmap.addr_bits <= addr_width <= 64:
            raise ValueError(f"addr_width must be an integer between {regmap.addr_bits} and "
                             f"64, not {addr_width!r}")
        if regmap.base >> addr_width:
            raise ValueError(f"base {regmap.base:#x} does not fit addr_width {addr_width}")
        self.params = regmap
        self.addr_width = addr_width
        members = {"axi": In(AXI4LiteSignature(addr_width))}
        for group in regmap.groups:
            if group.name == "axi" or hasattr(wiring.Component, group.name):
                raise ValueError(f"group name {group.name!r} is reserved")
            members[group.name] = Out(self._group_signature(group))
        super().__init__(members)

    @staticmethod
    def _group_signature(group):
        members = {}
        for reg in group.registers:
            if reg.access is Access.RW:
                members[reg.name] = Out(reg.port_shape())
            elif reg.access is Access.RO:
                members[reg.name] = In(reg.port_shape())
            elif reg.access is Access.WO:
                members[reg.name] = Out(command_signature(reg.port_shape(), reg.count))
        return wiring.Signature(members)

    def _decode(self, addr):
        """``(hit, word_index)``: ``hit`` when ``addr`` is an aligned address in the window."""
        regmap = self.params
        hit = addr[:2] == 0
        if self.addr_width > regmap.addr_bits:
            hit &= addr[regmap.addr_bits:] == (regmap.base >> regmap.addr_bits)
        return hit, addr[2:regmap.addr_bits]

    def elaborate(self, platform):
        regmap = self.params
        axi = self.axi
        m = Module()

        stored, commands = {}, {}
        for group in regmap.groups:
            port = getattr(self, group.name)
            for reg in group.registers:
                key = (group.name, reg.name)
                if reg.access is Access.RW:
                    init = sum(reg.reset_raw << (k * reg.width) for k in range(reg.count))
                    stored[key] = Signal(reg.width * reg.count, init=init,
                                         name=f"{group.name}_{reg.name}")
                    m.d.comb += Value.cast(getattr(port, reg.name)).eq(stored[key])
                elif reg.access is Access.WO:
                    cmd = getattr(port, reg.name)
                    data_sig = Signal(reg.width * reg.count, name=f"{group.name}_{reg.name}")
                    stb = Signal(reg.count, name=f"{group.name}_{reg.name}_stb")
                    commands[key] = (data_sig, stb)
                    m.d.comb += [Value.cast(cmd.data).eq(data_sig), cmd.stb.eq(stb)]
                    m.d.sync += stb.eq(0)

        # Writes: take address and data together, answer on B.
        b_valid = Signal()
        b_resp = Signal(2)
        take_write = axi.awvalid & axi.wvalid & ~b_valid
        mask = Cat(*(axi.wstrb[lane].replicate(8) for lane in range(4)))
        m.d.comb += [axi.awready.eq(take_write), axi.wready.eq(take_write),
                     axi.bvalid.eq(b_valid), axi.bresp.eq(b_resp)]
        with m.If(axi.bvalid & axi.bready):
            m.d.sync += b_valid.eq(0)
        with m.If(take_write):
            m.d.sync += [b_valid.eq(1), b_resp.eq(RESP_SLVERR)]
            hit, index = self._decode(axi.awaddr)
            with m.If(hit):
                with m.Switch(index):
                    for w in regmap.words():
                        key = (w.group.name, w.register.name)
                        access = w.register.access
                        if access not in (Access.RW, Access.WO):
                            continue
                        with m.Case(w.offset // WORD_BYTES):
                            if access is Access.RW:
                                target = _element(w, stored[key])
                                for piece in w.pieces():
                                    dst = slice(piece.dst, piece.dst + piece.width)
                                    old_bits = target[piece.src:piece.src + piece.width]
                                    m.d.sync += old_bits.eq((old_bits & ~mask[dst])
                                                            | (axi.wdata[dst] & mask[dst]))
                                m.d.sync += b_resp.eq(RESP_OKAY)
                            else:
                                data_sig, stb = commands[key]
                                target = _element(w, data_sig)
                                with m.If(axi.wstrb == 0b1111):
                                    m.d.sync += [target[p.src:p.src + p.width].eq(
                                        axi.wdata[p.dst:p.dst + p.width]) for p in w.pieces()]
                                    m.d.sync += b_resp.eq(RESP_OKAY)
                                    if w.last:
                                        m.d.sync += stb[w.index].eq(1)

        # Reads: one at a time. The decoded address is registered, and the word is read
        # the clock after through a balanced multiplexer tree on the index bits (issue 17:
        # the decoder, a case statement over every word and the status blocks' logic made
        # one 12-LUT-level path in the board top); answered then.
        r_pending, r_hit = Signal(), Signal()
        r_index = Signal(regmap.addr_bits - 2)
        r_valid = Signal()
        r_resp = Signal(2)
        r_data = Signal(32)
        m.d.comb += [axi.arready.eq(~r_pending & ~r_valid), axi.rvalid.eq(r_valid),
                     axi.rresp.eq(r_resp), axi.rdata.eq(r_data)]
        with m.If(axi.arvalid & axi.arready):
            hit, index = self._decode(axi.araddr)
            m.d.sync += [r_pending.eq(1), r_hit.eq(hit), r_index.eq(index)]
        snapshots = self._snapshots(m, r_pending & r_hit, r_index)
        readable = {}
        for w in regmap.words():
            reg = w.register
            if reg.access is Access.RW:
                source = stored[(w.group.name, reg.name)]
            elif reg.access is Access.RO:
                source = snapshots[(w.group.name, reg.name)] if w.word else \
                    self._status_port(w)
            elif reg.access is Access.CONST:
                source = Const(reg.value << (w.index * reg.width), reg.width * reg.count)
            else:
                continue
            readable[w.offset // WORD_BYTES] = self._word_value(w, _element(w, source))
        okay = Const(sum(1 << i for i in readable), 1 << len(r_index))
        with m.If(r_pending):
            m.d.sync += [r_pending.eq(0), r_valid.eq(1),
                         r_data.eq(Mux(r_hit, _select(readable, r_index), 0)),
                         r_resp.eq(Mux(r_hit & okay.bit_select(r_index, 1),
                                       RESP_OKAY, RESP_SLVERR))]
        with m.Elif(axi.rvalid & axi.rready):
            m.d.sync += r_valid.eq(0)
        return m

    def _status_port(self, w):
        """The flat port of ``w``'s read-only register."""
        return Value.cast(getattr(getattr(self, w.group.name), w.register.name))

    def _snapshots(self, m, reading, r_index):
        """A copy of every read-only register of several words, by ``(group, name)``:
        reading word 0 of an element (``reading`` with ``r_index`` on it) copies the
        whole element, and its other words answer from the copy, so an element read from
        word 0 upwards is one sample even when the block updates it between the reads (a
        torn read of a counter or of ``loop.track`` would be a silently wrong value)."""
        snapshots = {}
        for w in self.params.words():
            reg = w.register
            if reg.access is not Access.RO or reg.words == 1 or w.word:
                continue
            key = (w.group.name, reg.name)
            if key not in snapshots:
                snapshots[key] = Signal(reg.width * reg.count,
                                        name=f"{w.group.name}_{reg.name}_snap")
            snap = snapshots[key]
            with m.If(reading & (r_index == w.offset // WORD_BYTES)):
                m.d.sync += _element(w, snap).eq(_element(w, self._status_port(w)))
        return snapshots

    @staticmethod
    def _word_value(w, element):
        """The 32-bit word ``w`` read from its element's flat value (zeros between)."""
        parts, at = [], 0
        for piece in sorted(w.pieces(), key=lambda p: p.dst):
            if piece.dst > at:
                parts.append(Const(0, piece.dst - at))
            parts.append(element[piece.src:piece.src + piece.width])
            at = piece.dst + piece.width
        return Cat(*parts)


def _element(w, value):
    """Value of ``w``'s element inside the flat register ``value``."""
    width = w.register.width
    return value[w.index * width:(w.index + 1) * width]


def _select(words, index, bit=None):
    """``words[index]`` (a dict of word index → 32-bit value; 0 elsewhere) as a balanced
    tree of 2:1 multiplexers on the bits of ``index``, the highest first: its depth grows
    with the index width, not with the number of words as a case statement's does."""
    bit = len(index) - 1 if bit is None else bit
    if not words:
        return Const(0, 32)
    if bit < 0:
        (value,) = words.values()
        return value
    half = 1 << bit
    low = {i: v for i, v in words.items() if not i & half}
    high = {i & ~half: v for i, v in words.items() if i & half}
    return Mux(index[bit], _select(high, index, bit - 1), _select(low, index, bit - 1))
