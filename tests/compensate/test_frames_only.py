"""A calibration as a controller's base and tool (kincal.compensate.fit_frames_only, kincal.io.frames_data): the
frames of a robot that differs from its nominal only by a base and a tool point are found exactly (checked at
joints the fit never saw); what the frames leave of a full calibration is measured on its own; the KRL, RAPID
and URScript data, read by independent parsers (regular expressions and scipy's rotations), hold the frames;
the command line refuses what does not apply and writes nothing it could not read back."""
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kincal
import kincal.analysis
from kincal.compensate import fit_frames_only
from kincal.io import write_frames_data

NUMBER = r"[-+]?\d+(?:\.\d+)?"


def _T(rotvec, xyz):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_rotvec(rotvec).as_matrix(), xyz
    return T


def _flange(robot, q):
    p, R, _, _ = robot.with_tool_point(np.zeros(3)).pose_and_jacobian(q)
    T = np.tile(np.eye(4), (len(q), 1, 1))
    T[:, :3, :3], T[:, :3, 3] = R, p
    return T


def test_a_base_and_a_tool_point_are_found_exactly():
    nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point([0.0, 0.0, 0.05])
    moved = nominal.with_params({"base.x": 1.2, "base.y": -0.4, "base.z": 0.3, "base.rz": 0.7, "base.rx": 0.02})
    calibrated = moved.with_tool_point([0.011, -0.004, 0.182])
    fit = fit_frames_only(calibrated, nominal, samples=200, seed=3)
    assert fit.after_rms < 1e-10 and fit.after_max < 1e-9 and fit.rotation_after < 1e-9
    q = calibrated.sample_joints(50, seed=99)  # joints the fit never saw
    p, R, _, _ = calibrated.pose_and_jacobian(q)
    T = fit.base @ _flange(nominal, q) @ fit.tool
    assert np.abs(T[:, :3, 3] - p).max() < 1e-9 and np.abs(T[:, :3, :3] - R).max() < 1e-9
    assert np.abs(fit.tool[:3, 3] - [0.011, -0.004, 0.182]).max() < 1e-9


def test_what_the_frames_leave_of_a_full_calibration():
    """A perturbed arm (link lengths and joint zeros too): the fitted frames leave the RMS the fit reports, measured
    here at other joints; and they do better than the nominal arm with the perturbed one's base and tool point."""
    nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point([0.0, 0.0, 0.05])
    calibrated = kincal.perturb(nominal, seed=7)
    fit = fit_frames_only(calibrated, nominal, samples=400, seed=1)
    q = calibrated.sample_joints(2000, seed=42)
    p, _, _, _ = calibrated.pose_and_jacobian(q)
    left = np.linalg.norm((fit.base @ _flange(nominal, q) @ fit.tool)[:, :3, 3] - p, axis=1)
    assert abs(np.sqrt(np.mean(left**2)) - fit.after_rms) < 0.15 * fit.after_rms
    assert 1e-5 < fit.after_rms < fit.before_rms


@pytest.mark.parametrize("fmt, suffix", [("frames-krl", ".dat"), ("frames-rapid", ".mod"),
                                         ("frames-urscript", ".script")])
def test_the_controllers_data_hold_the_frames(tmp_path, fmt, suffix):
    rng = np.random.default_rng(4)
    base, tool = _T(rng.normal(size=3), rng.normal(size=3)), _T(rng.normal(size=3), rng.normal(size=3) * 0.1)
    path = tmp_path / f"cell_frames{suffix}"
    write_frames_data(str(path), fmt, base, tool, ["a note"], (2.5, 0.0, 0.0, 80.0))
    text = path.read_bytes().decode()
    if fmt == "frames-krl":
        assert text.startswith("&ACCESS RVP\r\nDEFDAT  CELL_FRAMES PUBLIC\r\n; a note\r\n")
        got = {}
        for name, *v in re.findall(rf"DECL GLOBAL FRAME (\w+)=\{{X ({NUMBER}),Y ({NUMBER}),Z ({NUMBER}),A ({NUMBER}),"
                                   rf"B ({NUMBER}),C ({NUMBER})\}}", text):
            x = np.array(v, float)
            got[name] = _T(Rotation.from_euler("ZYX", x[3:], degrees=True).as_rotvec(), x[:3] / 1e3)
        found = got["KINCAL_BASE"], got["KINCAL_TOOL"]
    elif fmt == "frames-rapid":
        poses = re.findall(rf"\[\[({NUMBER}),({NUMBER}),({NUMBER})\],\[({NUMBER}),({NUMBER}),({NUMBER}),({NUMBER})\]\]",
                           text)
        found = tuple(_T(Rotation.from_quat(np.array(v, float)[[4, 5, 6, 3]]).as_rotvec(), np.array(v[:3], float) / 1e3)
                      for v in (poses[0], poses[2]))  # the work object's user frame, the tool frame (poses[1]:
        assert poses[1] == ("0", "0", "0", "1", "0", "0", "0")  # the object frame, the identity)
        assert "[2.5,[0,0,80],[1,0,0,0],0,0,0]]" in text and "MODULE cell_frames" in text
    else:
        poses = re.findall(r"p\[([^\]]*)\]", text)
        found = tuple(_T(np.array(v.split(","), float)[3:], np.array(v.split(","), float)[:3]) for v in poses)
        assert text.index("kincal_base = p[") < text.index("set_tcp(p[")
    for meant, got in zip((base, tool), found):
        assert np.abs(got - meant).max() < 1e-9


def test_the_command_line_writes_frames_a_calibration_leaves(tmp_path, capsys):
    from kincal.cli import main

    nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point([0.0, 0.0, 0.05])
    measured = kincal.simulate(kincal.perturb(nominal, seed=3), nominal.sample_joints(60, seed=1), noise=0.0)
    res = kincal.calibrate(nominal, measured)
    cal = tmp_path / "cal.yaml"
    kincal.save_robot(res.robot, cal, calibration=res.record())

    def run(*argv):
        code = main(["export", str(cal), *argv])
        out = capsys.readouterr()
        return code, out.err + out.out

    code, said = run(str(tmp_path / "t.mod"), "--format", "frames-rapid")
    assert code != 0 and "--tool-load MASS,X,Y,Z" in said and not (tmp_path / "t.mod").exists()
    code, said = run(str(tmp_path / "t.dat"), "--format", "frames-krl", "--tool-load", "2,0,0,50")
    assert code != 0 and "for --format frames-rapid only" in said
    code, said = run(str(tmp_path / "t.dat"), "--format", "frames-krl", "--base-yaw", "3")
    assert code != 0 and "--base-yaw: not for frames data" in said
    code, said = run(str(tmp_path / "t.dat"), "--format", "frames-krl")
    assert code == 0 and "frames-krl written to" in said
    left = float(re.search(r"the frames alone leave RMS ([\d.]+) mm", said).group(1))
    unc = kincal.analysis.load_uncertainty(str(cal))  # the joint ranges of the calibration's data
    fit = fit_frames_only(res.robot, res.robot.with_params(res.record()["nominal"]), region=(unc.lower, unc.upper))
    assert "within the joint ranges of the calibration's data" in said
    assert abs(left - fit.after_rms * 1e3) < 1e-3
    v = np.array(re.search(r"KINCAL_TOOL=\{X (\S+),Y (\S+),Z (\S+),A (\S+),B (\S+),C ([^}]+)\}",
                           (tmp_path / "t.dat").read_text()).groups(), float)
    assert np.abs(v[:3] / 1e3 - fit.tool[:3, 3]).max() < 1e-9


@pytest.mark.parametrize("terms", [None, "compliance"])
def test_a_parallel_robot_is_refused_with_the_reason(terms):
    hexapod = kincal.load_robot("hexapod")
    robot = kincal.extend(hexapod, terms) if terms else hexapod
    with pytest.raises(kincal.errors.ModelError, match="frames data are a serial arm's base and tool"):
        fit_frames_only(robot, robot)
