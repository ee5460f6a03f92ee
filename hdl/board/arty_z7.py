"""Digilent Arty Z7-20 (xc7z020clg400-1): four DVP cameras on the Pmod and ChipKit
headers, the pose UART on Pmod JB.

Each camera's PCLK is on the P pin of a clock-capable pair (JA pin 7 = U18, ChipKit
IO29 = U7, IO37 = Y7, IO41 = Y9), the only four such pins the board brings to its
headers. The ChipKit digital pins have series resistors on the board; keep camera
cables short at the pixel clocks in mind here (up to 48 MHz).

Four cameras are all it can take: the board rig (eight cameras) needs 97 pins, eight of
them clock-capable, and the headers bring out 59 PL pins, four clock-capable; it is
built for the MicroZed 7020 (:mod:`hdl.board.microzed`).
"""

from amaranth_boards.arty_z7 import ArtyZ720Platform

from hdl.board.spec import BoardSpec, CameraPins
from hdl.board.zynq import XC7Z020_CLG400_CLOCK_P

__all__ = ["ARTY_Z7_20"]


def _ja(pin):
    return ("pmod", 0, str(pin))


def _jb(pin):
    return ("pmod", 1, str(pin))


def _ck(pin):
    return ("ck_io", 0, pin)


def _header_pins():
    """Package pins of the Pmod JA and JB and the ChipKit digital/analog headers."""
    return frozenset(pin for c in ArtyZ720Platform.connectors
                     if (c.name, c.number) in (("pmod", 0), ("pmod", 1), ("ck_io", 0))
                     for pin in c.mapping.values() if pin != "-")


ARTY_Z7_20 = BoardSpec(
    name="arty-z7-20",
    title="Digilent Arty Z7-20 (xc7z020clg400-1)",
    platform_class=ArtyZ720Platform,
    cameras=(
        CameraPins(pclk=_ja(7), vsync=_ja(1), href=_ja(2),
                   data=(_ja(3), _ja(4), _ja(8), _ja(9), _ja(10), _jb(1), _jb(3), _jb(4)),
                   fsin=_jb(7)),
        CameraPins(pclk=_ck("io29"), vsync=_ck("io26"), href=_ck("io27"),
                   data=tuple(_ck(f"io{n}") for n in (28, 30, 31, 32, 33, 34, 35, 36)),
                   fsin=_ck("io38")),
        CameraPins(pclk=_ck("io37"), vsync=_ck("io39"), href=_ck("io40"),
                   data=(*(_ck(f"a{n}") for n in range(6)), _jb(8), _jb(9)),
                   fsin=_jb(10)),
        CameraPins(pclk=_ck("io41"), vsync=_ck("io0"), href=_ck("io1"),
                   data=tuple(_ck(f"io{n}") for n in range(2, 10)), fsin=_ck("io10")),
    ),
    uart_tx=_jb(2),
    clock_capable=XC7Z020_CLG400_CLOCK_P,
    connector_names={("pmod", 0): "Pmod JA pin", ("pmod", 1): "Pmod JB pin",
                     ("ck_io", 0): "ChipKit"},
    user_pins=_header_pins(),
    notes="Four cameras in two stereo pairs cannot observe all six axes; the board rig "
          "(eight cameras) does not fit these headers and is built for the MicroZed 7020. "
          "The pose UART's TXD is on Pmod JB pin 2, the TXD position of a Digilent "
          "type-4 (UART) Pmod: a Pmod USBUART (or any 3.3 V USB-serial adapter's RXD) "
          "in the top row of JB receives the packets. The Arty Z7's own USB-UART is "
          "wired to the PS (MIO), not to the fabric.",
)
