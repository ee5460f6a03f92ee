"""Every block that can be written out as Verilog on its own, with its default build.

``rowtrack verilog NAME`` and ``make run`` read this table; each entry names a factory
that returns a ready-to-elaborate component with its default parameters. To add a block,
add a line here.
"""

import importlib

#: name -> "module:factory"
BLOCKS = {
    "mac": "hdl.pose.mac:MultiplyAccumulate",
    "dt_filter": "hdl.dt.filter:DomainTransformFilter",
    "dt_rounds": "hdl.dt.rounds:DomainTransformRounds",
    "uart": "hdl.output.uart:UartTx",
    "pose_output": "hdl.output.packet:PoseOutput",
    "regs": "hdl.top:register_file",
    "gp0_bridge": "hdl.board.gp0:GP0ToAXI4Lite",
    "top": "hdl.top:RowtrackTop",
    "top_closed": "hdl.top:closed_loop_top",
    "camera_input": "hdl.front_end.camera_input:CameraInput",
    "camera_sync": "hdl.front_end.camera_sync:CameraSync",
    "row_aligner": "hdl.front_end.row_aligner:RowAligner",
    "camera_front": "hdl.front_end.camera_sync:CameraFrontEnd",
    "pose_solver": "hdl.pose_solver:PoseSolver",
    "gain_solver": "hdl.pose_solver:default_gain_solver",
    "forecast": "hdl.pose.forecast:default_forecast",
    "status_unit": "hdl.pose.status_unit:default_status_unit",
    "prior_store": "hdl.pose.prior_store:default_prior_store",
    "motion_track": "hdl.pose.motion_track:default_motion_track",
    "row_counter": "hdl.pose.row_counter:default_row_counter",
    "row_descriptor": "hdl.row_descriptor:RowDescriptor",
    "stereo_row_descriptor": "hdl.row_descriptor:StereoRowDescriptor",
    "measurement_engine": "hdl.measurement.engine:MeasurementEngine",
    "follow_engine": "hdl.measurement.engine:default_follow_engine",
    "measurement_router": "hdl.measurement.router:default_router",
    "consistency_stage": "hdl.measurement.consistency:default_consistency_stage",
}


def names():
    return sorted(BLOCKS)


def build(name):
    """Instantiate block ``name`` with its default parameters."""
    if name not in BLOCKS:
        raise ValueError(f"block must be one of {', '.join(names())}, not {name!r}")
    module_name, factory = BLOCKS[name].split(":")
    return getattr(importlib.import_module(module_name), factory)()
