"""The board top shared by every Zynq board: PS7, GP0 bridge, tracker, pins.

:class:`ZynqTop` is what ``rowtrack build --board NAME`` elaborates: the PS7
(:mod:`hdl.board.ps7`) clocks the fabric from FCLK_CLK0 and reaches the register file
through M_AXI_GP0 and :class:`~hdl.board.gp0.GP0ToAXI4Lite`; each camera's PCLK pin
clocks its own domain (``pclk<k>``, reset from the system reset through a reset
synchronizer); the trigger outputs and the pose UART go to pins.
"""

from amaranth.build import ResourceError
from amaranth.hdl import ClockDomain, ClockSignal, Elaboratable, Module, ResetSignal, Signal
from amaranth.lib import io, wiring
from amaranth.lib.cdc import ResetSynchronizer

from hdl.front_end.params import CameraParams
from hdl.top import RowtrackTop
from hdl.top_params import TopParams
from hdl.board.gp0 import GP0ToAXI4Lite
from hdl.board.ps7 import FCLK0_NET, PS7
from hdl.board.spec import BoardSpec

__all__ = ["ZynqTop", "XC7Z020_CLG400_CLOCK_P"]

#: Package pins of xc7z020clg400 that are the P side of a clock-capable (MRCC/SRCC)
#: pair, among those the supported boards bring out (bank names from Digilent's
#: Arty Z7-20 master XDC).
XC7Z020_CLG400_CLOCK_P = frozenset({
    "U18", "N18", "U14", "N20",             # bank 34: L12P/L13P MRCC, L11P/L14P SRCC
    "U7", "Y7", "Y9",                       # bank 13: L11P SRCC, L13P MRCC, L14P SRCC
    "H16", "K17", "L16", "J18",             # bank 35: L13P/L12P MRCC, L11P/L14P SRCC
})


def default_params(board, fclk_hz=100_000_000):
    """The tracker parameters for ``board``: one camera per camera port, neighbouring
    ports paired for stereo ((0, 1), (2, 3), ...).

    Raises
    ------
    ValueError
        If the board has an odd number of camera ports (a camera without a pair).
    """
    if board.n_cameras % 2:
        raise ValueError(f"board {board.name} has {board.n_cameras} camera ports; the "
                         f"measurement engine needs stereo pairs")
    pairs = tuple((k, k + 1) for k in range(0, board.n_cameras, 2))
    return TopParams.for_pairs(pairs, camera=CameraParams(), clk_hz=fclk_hz)


class ZynqTop(Elaboratable):
    """The whole design for one board.

    Parameters
    ----------
    board : BoardSpec
    params : TopParams, optional
        Default: :func:`default_params`. ``camera.n_cameras`` must equal the board's
        camera ports; ``clk_hz`` is the FCLK_CLK0 frequency the PS is configured for.
        For a rig: ``hdl.top.board_config(rig, clk_hz=...).top``.
    coefficients : ndarray, optional
        The solver's initial coefficient store (a rig's ``PipelineConfig.coef_store``).
    forecast_stores : (ndarray, ndarray), closed loop only
        The forecast's stores (``PipelineConfig.forecast_stores``).
    """

    def __init__(self, board, params=None, coefficients=None, forecast_stores=None):
        if not isinstance(board, BoardSpec):
            raise TypeError(f"board must be a BoardSpec, not {board!r}")
        params = default_params(board) if params is None else params
        if not isinstance(params, TopParams):
            raise TypeError(f"params must be a TopParams, not {params!r}")
        if params.camera.n_cameras != board.n_cameras:
            raise ValueError(f"params.camera.n_cameras must be {board.n_cameras} (the camera "
                             f"ports of {board.name}), not {params.camera.n_cameras}")
        self.board = board
        self.params = params
        self.coefficients = coefficients
        self.forecast_stores = forecast_stores

    def elaborate(self, platform):
        m = Module()
        m.submodules.ps7 = ps7 = PS7(fclk_hz=self.params.clk_hz)
        m.domains += ClockDomain("sync")
        m.d.comb += ClockSignal("sync").eq(getattr(ps7, FCLK0_NET))
        m.submodules.reset_sync = ResetSynchronizer(ps7.reset, domain="sync")
        m.submodules.gp0 = bridge = GP0ToAXI4Lite()
        m.submodules.tracker = tracker = RowtrackTop(self.params, coefficients=self.coefficients,
                                                      forecast_stores=self.forecast_stores)
        wiring.connect(m, ps7.gp0, bridge.gp0)
        wiring.connect(m, bridge.lite, tracker.axi)

        for k, domain in enumerate(tracker.domains):
            pins = platform.request("camera", k, dir="-")
            buffers = {name: io.Buffer("o" if name == "fsin" else "i", getattr(pins, name))
                       for name in ("pclk", "vsync", "href", "data", "fsin")}
            for name, buffer in buffers.items():
                m.submodules[f"camera{k}_{name}"] = buffer
            m.domains += ClockDomain(domain)
            m.d.comb += ClockSignal(domain).eq(buffers["pclk"].i)
            m.submodules[f"{domain}_reset"] = ResetSynchronizer(ResetSignal("sync"),
                                                                domain=domain)
            m.d.comb += [tracker.dvp[k].vsync.eq(buffers["vsync"].i),
                         tracker.dvp[k].href.eq(buffers["href"].i),
                         tracker.dvp[k].data.eq(buffers["data"].i),
                         buffers["fsin"].o.eq(tracker.fsin[k])]
        m.submodules.uart_tx = uart = io.Buffer("o", platform.request("pose_uart", 0,
                                                                     dir="-").tx)
        m.d.comb += uart.o.eq(tracker.uart_tx)
        self._heartbeat(m, platform)
        return m

    def _heartbeat(self, m, platform):
        """Blink the board's first LED at about 1 Hz from FCLK_CLK0 (bring-up aid: the
        PS clock runs and the bitstream is loaded), if the board has one."""
        try:
            m.submodules.led = led = io.Buffer("o", platform.request("led", 0, dir="-"))
        except ResourceError:
            return
        counter = Signal(range(self.params.clk_hz // 2))
        blink = Signal()
        with m.If(counter == self.params.clk_hz // 2 - 1):
            m.d.sync += [counter.eq(0), blink.eq(~blink)]
        with m.Else():
            m.d.sync += counter.eq(counter + 1)
        m.d.comb += led.o.eq(blink)
