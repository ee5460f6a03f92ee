"""Avnet MicroZed 7020 (xc7z020clg400-1) on a carrier that brings out both
micro-headers: the board rig ``stereo8-board`` (eight DVP cameras in four stereo pairs)
and the pose UART.

JX1 carries bank 34 and JX2 bank 35, 50 PL pins each (the MicroZed's 100 user I/O;
the few bank-13 pins of the 7020 on JX1 87–94 and JX2 93–100 are left out). Each bank
has four clock-capable pairs: cameras 0–3 take bank 34's (PCLK on U18, N18, U14, N20),
cameras 4–7 bank 35's (H16, K17, L16, J18), 12 pins per camera. The banks' I/O voltage
comes from the carrier card; set ``iostandard`` to match it (3.3 V assumed here).
"""

from amaranth_boards.microzed_z020 import MicroZedZ020Platform

from hdl.board.spec import BoardSpec, CameraPins
from hdl.board.zynq import XC7Z020_CLG400_CLOCK_P

__all__ = ["MICROZED_7020"]

#: Connector pins of bank 34 on JX1 and of bank 35 on JX2 (the same numbers on both).
_BANK_PINS = (9, 10, 11, 12, 13, 14, 17, 18, 19, 20, 23, 24, 25, 26, 29, 30, 31, 32, 35,
              36, 37, 38, 41, 42, 43, 44, 47, 48, 49, 50, 53, 54, 55, 56, 61, 62, 63, 64,
              67, 68, 69, 70, 73, 74, 75, 76, 81, 82, 83, 84)
_JX2_BANK_PINS = (13, 14, *_BANK_PINS[6:], 87, 88, 89, 90)


def _pins(connector, *pins):
    return tuple((connector, 0, str(pin)) for pin in pins)


def _camera(connector, pclk, vsync, href, data, fsin):
    (pclk,), (vsync,), (href,), (fsin,) = (_pins(connector, p) for p in (pclk, vsync, href,
                                                                         fsin))
    return CameraPins(pclk=pclk, vsync=vsync, href=href, data=_pins(connector, *data),
                      fsin=fsin)


def _package_pins(connector, numbers):
    mapping = next(c.mapping for c in MicroZedZ020Platform.connectors
                   if c.name == connector)
    return {mapping[str(n)] for n in numbers}


MICROZED_7020 = BoardSpec(
    name="microzed-7020",
    title="Avnet MicroZed 7020 (xc7z020clg400-1), JX1 and JX2 on a carrier card",
    platform_class=MicroZedZ020Platform,
    cameras=(
        _camera("JX1", 42, 9, 10, (11, 12, 13, 14, 17, 18, 19, 20), 23),
        _camera("JX1", 47, 24, 25, (26, 29, 30, 31, 32, 35, 36, 37), 38),
        _camera("JX1", 41, 43, 44, (49, 50, 53, 54, 55, 56, 61, 62), 63),
        _camera("JX1", 48, 64, 67, (68, 69, 70, 73, 74, 75, 76, 81), 82),
        _camera("JX2", 53, 13, 14, (17, 18, 19, 20, 23, 24, 25, 26), 29),
        _camera("JX2", 48, 30, 31, (32, 35, 36, 37, 38, 41, 42, 43), 44),
        _camera("JX2", 47, 49, 50, (55, 56, 61, 62, 63, 64, 67, 68), 69),
        _camera("JX2", 54, 70, 73, (74, 75, 76, 81, 82, 83, 84, 87), 88),
    ),
    uart_tx=_pins("JX1", 83)[0],
    clock_capable=XC7Z020_CLG400_CLOCK_P,
    connector_names={("JX1", 0): "JX1 pin", ("JX2", 0): "JX2 pin"},
    user_pins=frozenset(_package_pins("JX1", _BANK_PINS) | _package_pins("JX2", _JX2_BANK_PINS)),
    rig="stereo8-board",
    notes="Cameras 0–3 and the UART are bank-34 pins of JX1, cameras 4–7 bank-35 pins of "
          "JX2 (the stereo pairs are cameras (0, 1), (2, 3), (4, 5), (6, 7)); the carrier "
          "card routes them to camera connectors and supplies both banks' VCCO. The "
          "MicroZed's USB-UART belongs to the PS; connect a 3.3 V USB-serial adapter's RXD "
          "to JX1 pin 83 for the pose packets.",
)
