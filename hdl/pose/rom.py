"""The pose engine's ROM contents: the scheduled row program packed one instruction word
per clock (:class:`ProgramRom`), and the seed unit's interpolation table."""

from amaranth.lib import data

from hdl.pose.params import SEED_TABLE_FMT, seed_tables
from hdl.pose.program import STATE_NAMES, allocate_work, build_row_program, schedule

__all__ = ["BANKS", "ProgramRom", "seed_table_contents"]

#: Register-bank codes of an instruction word's operands.
BANKS = {"input": 0, "work": 1, "state": 2, "constant": 3}


def seed_table_contents(params):
    """ROM words of the seed unit: ``T1 << T0_width | T0`` for each table index."""
    values, slopes = seed_tables(params.seed_bits)
    width = SEED_TABLE_FMT.width
    return [(s << width) | v for v, s in zip(values, slopes)]


class ProgramRom:
    """The program as ROM words (one per clock) and the static tables the datapath needs."""

    def __init__(self, params, information=False):
        self.program = build_row_program(params, information)
        self.schedule = schedule(self.program)
        #: work-bank register of each work value, and the bank's depth (:func:`allocate_work`)
        self.work_register, self.work_depth = allocate_work(self.program, self.schedule)
        ops = self.program.ops
        self.init_shifts = sorted({op.init_shift for op in ops if op.kind == "mac" and op.init})
        self.out_shifts = sorted({op.out_shift for op in ops if op.kind == "mac"})
        #: the (init, out) shift pairs that occur, as ((code, shift), (code, shift))
        self.init_out_pairs = sorted({
            ((self.init_shifts.index(op.init_shift), op.init_shift),
             (self.out_shifts.index(op.out_shift), op.out_shift))
            for op in ops if op.kind == "mac" and op.init})
        self.max_terms = max(op.slots for op in ops)
        self.index_bits = max(len(self.program.inputs), self.work_depth,
                              len(STATE_NAMES), len(self.program.constants)).bit_length()
        # capture codes: 1-6 the step, 7-12 the information gain's moves
        step_names = {v.name: k for k, v in
                      enumerate(self.program.step + self.program.gain_step)}
        b = self.index_bits
        gain = {"gain": 1} if information else {}
        self.layout = data.StructLayout({
            "issue": 1, "seed": 1, "first": 1, "last": 1, "negate": 1, "has_init": 1,
            "a_bank": 2, "a": b, "b_bank": 2, "b": b, "c_bank": 2, "c": b,
            "init_code": max(1, len(self.init_shifts).bit_length()),
            "out_code": max(1, len(self.out_shifts).bit_length()),
            "dst_state": 1, "dst": b, "checked": 1,
            "capture": 4 if information else 3, **gain,
        })
        words = [dict() for _ in range(self.schedule.length)]
        for op, start in zip(ops, self.schedule.issue):
            if op.kind == "seed":
                words[start] = {"issue": 1, "seed": 1, "first": 1, "last": 1,
                                "a_bank": BANKS[op.source.bank], "a": self.address(op.source),
                                "dst": self.address(op.dst), "gain": int(op.group == "gain")}
                continue
            for t, (sign, a, bb) in enumerate(op.terms):
                word = {"issue": 1, "negate": int(sign < 0), "first": int(t == 0),
                        "last": int(t == len(op.terms) - 1),
                        "a_bank": BANKS[a.bank], "a": self.address(a),
                        "b_bank": BANKS[bb.bank], "b": self.address(bb),
                        "out_code": self.out_shifts.index(op.out_shift),
                        "dst_state": int(op.commit), "dst": self.address(op.dst),
                        "checked": int(op.checked), "gain": int(op.group == "gain"),
                        "capture": step_names.get(op.dst.name, -1) + 1}
                if t == 0 and op.init is not None:
                    word.update(has_init=1, c_bank=BANKS[op.init.bank], c=self.address(op.init),
                                init_code=self.init_shifts.index(op.init_shift))
                words[start + t] = word
        self.words = [self._pack(w) for w in words]

    def address(self, operand):
        """``operand``'s address in its bank: the allocated register of a work value."""
        return self.work_register[operand.name] if operand.bank == "work" else operand.index

    def _pack(self, word):
        value = 0
        for name, field in self.layout:
            value |= (word.get(name, 0) & ((1 << field.width) - 1)) << field.offset
        return value
