"""Pose output: pose records, framed packets with CRC-16, decimation and the PS FIFO.

The tracker emits one pose per image row (tens to hundreds of kHz); a UART carries a few
thousand packets per second. :class:`PoseOutput` therefore

1. *decimates*: keeps one pose in ``decimation`` and numbers the kept ones (``seq``);
2. hands every kept record to two sinks, each with a one-record slot that drops (and
   counts) a record when it is still full: the packet :class:`Framer` feeding the UART,
   and a FIFO the PS drains through registers. A record tells how many its sink dropped
   just before it (``skipped``), so a receiver can tell poses skipped by the hardware
   from packets lost on the wire;
3. counts everything (poses in, kept, decimated away, dropped per sink, packets) and
   measures the pose rate over a programmable window.

It never stalls the tracker: ``pose.ready`` is always high.

The packet layout is declared once in :class:`hdl.output.params.PacketParams` and shared
with the bit-accurate model (:mod:`emulator.output.packets`) and the host tool
(:mod:`emulator.output.host`).
"""

from amaranth.hdl import Cat, Const, Module, Mux, Signal, Value
from amaranth.lib import stream, wiring
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from hdl.fixed import Overflow, Rounding, hdl_resize
from hdl.output.params import CRC16_INIT, CRC16_POLY, PacketParams, PoseOutputParams

__all__ = ["crc16_step", "Framer", "PoseOutput"]

def crc16_step(crc, byte):
    """Gateware: the CRC-16/CCITT-FALSE register after shifting in ``byte`` (MSB first).

    Combinational, eight unrolled steps of the bitwise algorithm (about one LUT level
    per output bit after synthesis); the model is :func:`emulator.output.packets.crc16`.
    """
    for i in range(8):
        feedback = crc[15] ^ byte[7 - i]
        crc = Cat(Const(0, 1), crc[:15]) ^ Mux(feedback, CRC16_POLY, 0)
        crc = crc[:16]
    return crc


class Framer(wiring.Component):
    """Serializes pose records into packets, one byte per transfer, with the CRC.

    Parameters
    ----------
    params : PacketParams

    Members
    -------
    i : In(stream.Signature(params.record_layout()))
        Records to frame; taken only between packets.
    o : Out(stream.Signature(8))
        Packet bytes in wire order (:class:`PacketParams`).

    Latency: the first byte is valid the clock after a record is taken; bytes follow
    back to back as ``o`` takes them. Throughput: one packet per ``packet_bytes``
    transfers plus one idle clock. Reset: drops a packet in flight.
    """

    def __init__(self, params=PacketParams()):
        if not isinstance(params, PacketParams):
            raise TypeError(f"params must be a PacketParams, not {params!r}")
        self.params = params
        super().__init__({
            "i": In(stream.Signature(params.record_layout())),
            "o": Out(stream.Signature(8)),
        })

    def _record_bytes(self, record):
        """The payload bytes of ``record`` in wire order (little-endian fields)."""
        out = []
        for field in self.params.fields():
            value = record[field.name]
            elements = [value] if field.count == 1 else [value[k] for k in range(field.count)]
            for element in elements:
                bits = Value.cast(element)
                out += [bits[8 * k:8 * k + 8] for k in range(field.bits // 8)]
        return out

    def elaborate(self, platform):
        p = self.params
        m = Module()
        record = Signal(p.record_layout())
        busy = Signal()
        index = Signal(range(p.packet_bytes))
        crc = Signal(16, init=CRC16_INIT)

        crc_at = p.packet_bytes - 2
        body = [Const(p.sync >> 8, 8), Const(p.sync & 0xFF, 8), Const(p.payload_bytes, 8),
                *self._record_bytes(record), crc[8:16], crc[0:8]]
        byte = Cat(*body).word_select(index, 8)

        m.d.comb += [self.i.ready.eq(~busy), self.o.valid.eq(busy), self.o.payload.eq(byte)]
        with m.If(self.i.valid & self.i.ready):
            m.d.sync += [record.eq(self.i.payload), busy.eq(1), index.eq(0),
                         crc.eq(CRC16_INIT)]
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += index.eq(index + 1)
            with m.If((index >= 2) & (index < crc_at)):
                m.d.sync += crc.eq(crc16_step(crc, byte))
            with m.If(index == p.packet_bytes - 1):
                m.d.sync += busy.eq(0)
        return m


class PoseOutput(wiring.Component):
    """Decimates poses into numbered records and feeds the UART framer and the PS FIFO.

    Parameters
    ----------
    params : PoseOutputParams

    Members
    -------
    pose : In(stream.Signature(source.layout()))
        Poses from the tracker in its formats (:class:`PoseSource`); ``ready`` is
        always high (the output never stalls it).
    cfg : In(params.config_layout())
        Run-time control (registers).
    uart : Out(stream.Signature(8))
        Packet bytes for :class:`hdl.output.uart.UartTx`.
    fifo : Out(stream.Signature(packet.record_layout()))
        The head of the PS FIFO; a register write pops it (``ready``).
    status : Out(params.status_layout())
        Counters.

    Latency: a kept pose reaches the framer slot and the FIFO one clock after its
    transfer. Throughput: one pose per clock. Reset: clears counters, the FIFO and both
    slots.
    """

    def __init__(self, params=PoseOutputParams()):
        if not isinstance(params, PoseOutputParams):
            raise TypeError(f"params must be a PoseOutputParams, not {params!r}")
        self.params = params
        packet = params.packet
        super().__init__({
            "pose": In(stream.Signature(params.source.layout())),
            "cfg": In(params.config_layout()),
            "uart": Out(stream.Signature(8)),
            "fifo": Out(stream.Signature(packet.record_layout())),
            "status": Out(params.status_layout()),
        })

    def elaborate(self, platform):
        p = self.params
        packet = p.packet
        m = Module()
        m.submodules.framer = framer = Framer(packet)
        m.submodules.fifo = fifo = SyncFIFOBuffered(width=packet.record_layout().size,
                                                    depth=p.fifo_depth)
        count = Signal(p.status_layout())            # every field but fifo_level: sync
        # A record on its way into the FIFO's output register is not counted yet, so
        # ``fifo_head`` is valid whenever ``fifo_level`` is not zero.
        m.d.comb += [self.status.eq(count),
                     self.status.fifo_level.eq(Mux(fifo.r_rdy, fifo.level, 0)),
                     self.pose.ready.eq(1)]

        def increment(name):
            return getattr(count, name).eq(getattr(count, name) + 1)

        # 1. Decimation and numbering: `record` holds the newest kept pose while `kept`.
        phase = Signal(p.decimation_bits)
        seq = Signal(packet.seq_bits)
        kept = Signal()
        record = Signal(packet.record_layout())
        m.d.sync += kept.eq(self.pose.valid & (phase == 0))
        with m.If(self.pose.valid):
            m.d.sync += [increment("poses"),
                         phase.eq(Mux(phase + 1 >= self.cfg.decimation, 0, phase + 1))]
            with m.If(phase == 0):
                m.d.sync += [increment("records"), seq.eq(seq + 1), record.seq.eq(seq)]
                m.d.sync += self._narrow(record, self.pose.payload)
            with m.Else():
                m.d.sync += increment("decimated")

        # 2. Two sinks that drop (and count) a record when they are still full.
        uart_slot = Signal(packet.record_layout())
        uart_full = Signal()
        uart_take, uart_skipped = self._sink(m, kept, enable=self.cfg.uart_enable,
                                             room=~uart_full | framer.i.ready,
                                             dropped=increment("uart_dropped"))
        with m.If(uart_take):
            m.d.sync += [uart_slot.eq(record), uart_slot.skipped.eq(uart_skipped),
                         uart_full.eq(1), increment("packets")]
        with m.Elif(framer.i.ready):
            m.d.sync += uart_full.eq(0)
        m.d.comb += [framer.i.valid.eq(uart_full), framer.i.payload.eq(uart_slot)]
        wiring.connect(m, framer.o, wiring.flipped(self.uart))

        fifo_take, fifo_skipped = self._sink(m, kept, enable=self.cfg.fifo_enable,
                                             room=fifo.w_rdy, dropped=increment("fifo_dropped"))
        fifo_record = Signal(packet.record_layout())
        m.d.comb += [fifo_record.eq(record), fifo_record.skipped.eq(fifo_skipped),
                     fifo.w_data.eq(fifo_record), fifo.w_en.eq(fifo_take),
                     self.fifo.valid.eq(fifo.r_rdy), self.fifo.payload.eq(fifo.r_data),
                     fifo.r_en.eq(self.fifo.ready)]

        # 3. Pose rate: poses in the last complete window of `rate_window` clocks.
        window_clock = Signal(p.count_bits)
        window_poses = Signal(p.count_bits)
        with m.If(self.cfg.rate_window == 0):
            m.d.sync += [window_clock.eq(0), window_poses.eq(0)]
        with m.Elif(window_clock + 1 >= self.cfg.rate_window):
            m.d.sync += [window_clock.eq(0), window_poses.eq(self.pose.valid),
                         count.pose_rate.eq(window_poses + self.pose.valid)]
        with m.Else():
            m.d.sync += [window_clock.eq(window_clock + 1),
                         window_poses.eq(window_poses + self.pose.valid)]
        return m

    def _narrow(self, record, pose):
        """Assignments of ``pose`` (source formats) to ``record`` (packet formats)."""
        src, packet = self.params.source, self.params.packet
        out = [record.t_row.eq(pose.time[:packet.timestamp_bits]), record.row.eq(pose.row),
               record.flags.eq(pose.flags)]
        for name, value, src_fmt, dst_fmt, count in (
                ("position", pose.p, src.position_fmt, packet.position_fmt, 3),
                ("quaternion", pose.q, src.quaternion_fmt, packet.quaternion_fmt, 4)):
            for k in range(count):
                out.append(getattr(record, name)[k].eq(hdl_resize(
                    value[k], src_fmt, dst_fmt, Rounding.HALF_EVEN, Overflow.SATURATE)))
        return out

    def _sink(self, m, kept, *, enable, room, dropped):
        """Drop-when-full bookkeeping of one sink.

        Returns ``(take, skipped)``: ``take`` strobes when the sink takes the kept
        record; ``skipped`` is how many kept records it dropped since the last one it
        took (saturating), to be stored with the record it takes. A disabled sink
        neither takes nor counts.
        """
        bits = self.params.packet.skipped_bits
        skipped = Signal(bits)
        take = Signal()
        m.d.comb += take.eq(kept & enable & room)
        with m.If(take):
            m.d.sync += skipped.eq(0)
        with m.Elif(kept & enable):
            m.d.sync += dropped
            with m.If(skipped != (1 << bits) - 1):
                m.d.sync += skipped.eq(skipped + 1)
        return take, skipped
