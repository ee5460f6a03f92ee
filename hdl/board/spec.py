"""What a board contributes to a build: pins for the cameras and the UART, as data.

A :class:`BoardSpec` names connector pins (``(connector, number, pin)`` as
amaranth-boards declares them); :meth:`BoardSpec.platform` resolves them to package
pins and returns the amaranth-boards platform with ``camera`` and ``pose_uart``
resources added, and :meth:`BoardSpec.pin_table` documents the assignment
(``docs/board.md``).
"""

from dataclasses import dataclass

from amaranth.build import Attrs, Clock, Pins, Resource, Subsignal

__all__ = ["CameraPins", "BoardSpec", "CAMERA_SIGNALS", "DATA_PINS", "PINS_PER_CAMERA"]

#: A DVP camera's signals, in the order of :class:`CameraPins`.
CAMERA_SIGNALS = ("pclk", "vsync", "href", "data", "fsin")
#: A camera's data pins (8-bit pixels), and the package pins a camera takes.
DATA_PINS = 8
PINS_PER_CAMERA = len(CAMERA_SIGNALS) - 1 + DATA_PINS


@dataclass(frozen=True)
class CameraPins:
    """One camera's connector pins: each a ``(connector, number, pin)`` triple.

    ``pclk`` must be the P side of a clock-capable (MRCC/SRCC) pair so that it can
    drive a global clock buffer; ``data`` lists D0 first.
    """
    pclk: tuple
    vsync: tuple
    href: tuple
    data: tuple
    fsin: tuple


@dataclass(frozen=True)
class BoardSpec:
    """A Zynq board the design builds for.

    Parameters
    ----------
    name : str
        The ``--board`` name.
    title : str
    platform_class : type
        The amaranth-boards platform.
    cameras : tuple of CameraPins
    uart_tx : tuple
        ``(connector, number, pin)`` of the pose UART's TXD.
    clock_capable : frozenset of str
        Package pins of the P side of clock-capable pairs (checked for every ``pclk``).
    iostandard : str
        I/O standard of the camera and UART pins.
    pclk_hz : float
        Fastest pixel clock the constraints allow for.
    notes : str
        Wiring notes for ``docs/board.md``.
    connector_names : dict
        Board-silkscreen names of amaranth-boards connectors, ``(name, number) -> str``,
        for the pin table.
    user_pins : frozenset of str
        Package pins of the PL user I/O the board brings to its connectors (from the
        board's documentation), to count the pins a build leaves free; every assigned
        pin must be one of them. Empty: not counted.
    rig : str, optional
        The rig preset whose closed-loop top ``rowtrack build --board`` builds by
        default (:func:`hdl.top.board_config`); None: the ports paired and an empty
        coefficient store (:func:`hdl.board.zynq.default_params`).
    """
    name: str
    title: str
    platform_class: type
    cameras: tuple
    uart_tx: tuple
    clock_capable: frozenset
    iostandard: str = "LVCMOS33"
    pclk_hz: float = 48e6
    notes: str = ""
    connector_names: dict = None
    user_pins: frozenset = frozenset()
    rig: str = None

    def __post_init__(self):
        for k, cam in enumerate(self.cameras):
            if len(cam.data) != DATA_PINS:
                raise ValueError(f"camera {k} of {self.name} must have {DATA_PINS} data pins, "
                                 f"not {len(cam.data)}")
            if self.resolve(cam.pclk) not in self.clock_capable:
                raise ValueError(f"pclk of camera {k} on {self.name} must be a clock-capable "
                                 f"P pin, not {self.resolve(cam.pclk)}")
        physical = self.pins_used()
        twice = {p for p in physical if physical.count(p) > 1}
        if twice:
            raise ValueError(f"pin {sorted(twice)[0]} of {self.name} is assigned twice")
        outside = sorted(set(physical) - self.user_pins) if self.user_pins else []
        if outside:
            raise ValueError(f"pin {outside[0]} of {self.name} is not one of its user_pins")

    def pins_used(self):
        """Package pins the cameras and the UART take."""
        pins = [self.uart_tx]
        for cam in self.cameras:
            pins += [cam.pclk, cam.vsync, cam.href, *cam.data, cam.fsin]
        return [self.resolve(pin) for pin in pins]

    def pins_left(self):
        """Package pins of :attr:`user_pins` no camera or UART takes, sorted."""
        return sorted(self.user_pins - set(self.pins_used()))

    @property
    def n_cameras(self):
        return len(self.cameras)

    def resolve(self, pin):
        """The package pin behind connector pin ``(connector, number, pin)``."""
        name, number, label = pin
        for connector in self.platform_class.connectors:
            if connector.name == name and connector.number == number:
                if str(label) not in connector.mapping:
                    raise ValueError(f"connector {name}{number} of {self.name} has no pin "
                                     f"{label!r}")
                return connector.mapping[str(label)]
        raise ValueError(f"{self.name} has no connector {name}{number}")

    def resources(self):
        """``camera`` (one per camera) and ``pose_uart`` resources on package pins."""
        attrs = Attrs(IOSTANDARD=self.iostandard)
        out = []
        for k, cam in enumerate(self.cameras):
            out.append(Resource(
                "camera", k,
                Subsignal("pclk", Pins(self.resolve(cam.pclk), dir="i"), Clock(self.pclk_hz)),
                Subsignal("vsync", Pins(self.resolve(cam.vsync), dir="i")),
                Subsignal("href", Pins(self.resolve(cam.href), dir="i")),
                Subsignal("data", Pins(" ".join(self.resolve(p) for p in cam.data), dir="i")),
                Subsignal("fsin", Pins(self.resolve(cam.fsin), dir="o")),
                attrs))
        out.append(Resource("pose_uart", 0,
                            Subsignal("tx", Pins(self.resolve(self.uart_tx), dir="o")), attrs))
        return out

    def platform(self):
        """An instance of the board's platform with the design's resources added."""
        platform = self.platform_class()
        platform.add_resources(self.resources())
        return platform

    def pin_table(self):
        """Markdown table: signal, connector pin, package pin."""
        rows = ["| signal | connector pin | package pin |", "|---|---|---|"]

        names = self.connector_names or {}

        def row(signal, pin):
            name, number, label = pin
            connector = names.get((name, number), f"{name}{number}")
            rows.append(f"| {signal} | {connector} {label} | {self.resolve(pin)} |")

        for k, cam in enumerate(self.cameras):
            row(f"camera {k} PCLK", cam.pclk)
            row(f"camera {k} VSYNC", cam.vsync)
            row(f"camera {k} HREF", cam.href)
            for bit, pin in enumerate(cam.data):
                row(f"camera {k} D{bit}", pin)
            row(f"camera {k} FSIN (out)", cam.fsin)
        row("pose UART TXD (out)", self.uart_tx)
        if self.user_pins:
            left = self.pins_left()
            rows.append(f"\n{len(self.pins_used())} of the board's {len(self.user_pins)} "
                        f"user PL pins on these connectors are taken; {len(left)} left"
                        + (f" ({', '.join(left)})." if left else "."))
        return "\n".join(rows)
