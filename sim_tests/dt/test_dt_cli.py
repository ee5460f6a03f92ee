"""``rowtrack dts`` and ``rowtrack dtfilter`` on image files."""

import re

import cv2
import numpy as np
import pytest

from emulator.cli import main
from emulator.dt.filter import filter_frame, sigma_register
from golden.dt_scenes import bicubic_target, downsample, make_scene, rmse
from golden.dts import DtsParams, dts, target_confidence
from hdl.dt.params import DtFilterParams


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A guide and a 4x-upsampled noisy depth target, as 8- and 16-bit PNGs."""
    directory = tmp_path_factory.mktemp("dt_cli")
    scene = make_scene(192, 256, seed=4)
    target = bicubic_target(downsample(scene.depth, 4, noise=2.0, seed=4), 4)
    paths = {"guide": directory / "guide.png", "t8": directory / "target8.png",
             "t16": directory / "target16.png", "conf": directory / "conf.png"}
    cv2.imwrite(str(paths["guide"]), scene.guide)
    cv2.imwrite(str(paths["t8"]), np.clip(np.rint(target), 0, 255).astype(np.uint8))
    cv2.imwrite(str(paths["t16"]), np.rint(target * 257).astype(np.uint16))
    cv2.imwrite(str(paths["conf"]), np.full(target.shape, 77, np.uint8))
    return directory, paths, scene


@pytest.mark.parametrize("target, scale", [("t8", 1.0), ("t16", 257.0)])
def test_dts_keeps_bit_depth_and_scale(files, target, scale):
    directory, paths, scene = files
    out_path = directory / f"out_{target}.png"
    assert main(["dts", "--guide", str(paths["guide"]), "--target", str(paths[target]),
                 "-o", str(out_path)]) == 0
    target_image = cv2.imread(str(paths[target]), cv2.IMREAD_UNCHANGED)
    out = cv2.imread(str(out_path), cv2.IMREAD_UNCHANGED)
    assert out.dtype == target_image.dtype and out.shape == target_image.shape
    values = target_image.astype(float)
    solved = dts(values, cv2.imread(str(paths["guide"])) / 255.0, target_confidence(values))
    np.testing.assert_array_equal(out, np.clip(np.rint(solved), 0, 255 * scale))
    assert rmse(out / scale, scene.depth) < rmse(target_image / scale, scene.depth)


def test_dts_reads_a_confidence_map_and_options(files):
    directory, paths, _ = files
    out_path = directory / "out_conf.png"
    assert main(["dts", "--guide", str(paths["guide"]), "--target", str(paths["t8"]),
                 "--confidence", str(paths["conf"]), "-o", str(out_path), "--sigma-s", "10",
                 "--sigma-r", "0.1", "--lam", "0.9", "--iterations", "3", "--robust", "5",
                 "--hard", "1", "--norm", "l2", "--factor", "8", "--depth-sigma", "0.2",
                 "--depth-smoothing", "0"]) == 0
    assert cv2.imread(str(out_path), cv2.IMREAD_UNCHANGED).dtype == np.uint8


def test_dts_factor_and_colour_only_are_the_golden_settings(files):
    directory, paths, _ = files
    out_path = directory / "out_factor.png"
    assert main(["dts", "--guide", str(paths["guide"]), "--target", str(paths["t8"]),
                 "-o", str(out_path), "--factor", "8", "--colour-only"]) == 0
    values = cv2.imread(str(paths["t8"]), cv2.IMREAD_UNCHANGED).astype(float)
    solved = dts(values, cv2.imread(str(paths["guide"])) / 255.0, target_confidence(values),
                 DtsParams.for_factor(8, depth_sigma=None))
    np.testing.assert_array_equal(cv2.imread(str(out_path), cv2.IMREAD_UNCHANGED),
                                  np.clip(np.rint(solved), 0, 255))


@pytest.mark.parametrize("args, message", [
    (["--sigma-s", "0"], "--sigma-s must be a number greater than 0, not 0.0"),
    (["--iterations", "0"], "--iterations must be an integer at least 1, not 0"),
    (["--hard", "2"], "--hard must be a number greater than 0 and at most 1, not 2.0"),
    (["--factor", "0"], "--factor must be a number greater than 0, not 0.0"),
    (["--depth-sigma", "-1"], "--depth-sigma must be a number greater than 0, not -1.0"),
    (["--depth-smoothing", "-2"],
     "--depth-smoothing must be a number greater than 0, not -2.0"),
    (["--confidence", "missing.png"], "--confidence 'missing.png' does not exist"),
])
def test_dts_bad_input_is_a_clear_error(files, capsys, args, message):
    directory, paths, _ = files
    code = main(["dts", "--guide", str(paths["guide"]), "--target", str(paths["t8"]),
                 "-o", str(directory / "never.png"), *args])
    assert code == 2
    assert re.search(message, capsys.readouterr().err)
    assert not (directory / "never.png").exists()


def test_dts_rejects_mismatched_sizes(files, capsys):
    directory, paths, _ = files
    small = directory / "small.png"
    cv2.imwrite(str(small), np.zeros((10, 12), np.uint8))
    assert main(["dts", "--guide", str(paths["guide"]), "--target", str(small),
                 "-o", str(directory / "never.png")]) == 2
    assert "--target must have the guide's size 256x192, not 12x10" in capsys.readouterr().err


@pytest.mark.parametrize("method", ["rf", "nc"])
def test_dtfilter_smooths_and_keeps_bit_depth(files, method):
    directory, paths, _ = files
    out_path = directory / f"smooth_{method}.png"
    assert main(["dtfilter", str(paths["t16"]), "--guide", str(paths["guide"]),
                 "-o", str(out_path), "--method", method, "--sigma-s", "20"]) == 0
    source = cv2.imread(str(paths["t16"]), cv2.IMREAD_UNCHANGED)
    out = cv2.imread(str(out_path), cv2.IMREAD_UNCHANGED)
    assert out.dtype == np.uint16 and out.shape == source.shape
    roughness = [np.abs(np.diff(img.astype(float), axis=1)).mean() for img in (source, out)]
    assert roughness[1] < roughness[0]


def test_dtfilter_hardware_is_the_emulator(files):
    directory, paths, _ = files
    out_path = directory / "hardware.png"
    assert main(["dtfilter", str(paths["t8"]), "--guide", str(paths["guide"]), "-o",
                 str(out_path), "--hardware", "--window", "4", "--sigma-s", "12",
                 "--sigma-r", "0.2"]) == 0
    guide = cv2.cvtColor(cv2.imread(str(paths["guide"])), cv2.COLOR_BGR2GRAY)
    value = cv2.imread(str(paths["t8"]), cv2.IMREAD_UNCHANGED)
    expected = filter_frame(DtFilterParams(width=256, window=4), guide, value,
                            sigma_register("s", 12.0), sigma_register("r", 0.2 * 255))
    np.testing.assert_array_equal(cv2.imread(str(out_path), cv2.IMREAD_UNCHANGED), expected)


def test_dtfilter_bad_input_is_a_clear_error(files, capsys):
    directory, paths, _ = files
    assert main(["dtfilter", str(paths["guide"]), "-o", str(directory / "x.png"),
                 "--hardware"]) == 2
    assert "--hardware filters single-channel images only" in capsys.readouterr().err
    assert main(["dtfilter", str(paths["t8"]), "-o", str(directory / "x.png"), "--hardware",
                 "--window", "0"]) == 2
    assert "--window must be an integer between 1 and 64, not 0" in capsys.readouterr().err
    assert main(["dtfilter", str(paths["t8"]), "-o", str(directory / "x.unknownext")]) == 2
    assert "OpenCV cannot write this file type" in capsys.readouterr().err
