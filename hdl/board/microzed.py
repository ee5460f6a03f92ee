"""Avnet MicroZed 7020 (xc7z020clg400-1) on a carrier that brings out the JX1
micro-header: four DVP cameras and the pose UART on bank 34.

The second board shows the design is portable: the same tracker, PS7 wrapper and
build flow, only the pin table differs. Each PCLK is on the P pin of a clock-capable
pair (U18, N18, U14, N20). Bank 34's I/O voltage comes from the carrier card; set
``iostandard`` to match it (3.3 V assumed here).
"""

from amaranth_boards.microzed_z020 import MicroZedZ020Platform

from hdl.board.spec import BoardSpec, CameraPins
from hdl.board.zynq import XC7Z020_CLG400_CLOCK_P

__all__ = ["MICROZED_7020"]


def _jx1(*pins):
    return tuple(("JX1", 0, str(pin)) for pin in pins)


def _camera(pclk, vsync, href, data, fsin):
    (pclk,), (vsync,), (href,), (fsin,) = _jx1(pclk), _jx1(vsync), _jx1(href), _jx1(fsin)
    return CameraPins(pclk=pclk, vsync=vsync, href=href, data=_jx1(*data), fsin=fsin)


MICROZED_7020 = BoardSpec(
    name="microzed-7020",
    title="Avnet MicroZed 7020 (xc7z020clg400-1), JX1 on a carrier card",
    platform_class=MicroZedZ020Platform,
    cameras=(
        _camera(42, 9, 10, (11, 12, 13, 14, 17, 18, 19, 20), 23),
        _camera(47, 24, 25, (26, 29, 30, 31, 32, 35, 36, 37), 38),
        _camera(41, 43, 44, (49, 50, 53, 54, 55, 56, 61, 62), 63),
        _camera(48, 64, 67, (68, 69, 70, 73, 74, 75, 76, 81), 82),
    ),
    uart_tx=_jx1(83)[0],
    clock_capable=XC7Z020_CLG400_CLOCK_P,
    connector_names={("JX1", 0): "JX1 pin"},
    notes="All camera and UART pins are bank-34 pins of the JX1 micro-header; the "
          "carrier card routes them to camera connectors and supplies the bank's VCCO. "
          "The MicroZed's USB-UART belongs to the PS; connect a 3.3 V USB-serial "
          "adapter's RXD to JX1 pin 83 for the pose packets.",
)
