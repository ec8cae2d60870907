"""Error models beyond geometry in the fit of observation sets: a compliance fitted from 6-D poses
against the true robot's, a negative compliance dropped as in the position fit, and the command
line's --error-model for pose data, kept in the record so kincal report repeats the fit."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kincal
from kincal.cli import main
from kincal.identify import fit_observations
from kincal.models.terms import TAU_REF, drop_terms, extend
from kincal.observe import ObservationFormat, write_observations
from kincal.simulate.observations import simulate_poses

TARGET = Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix()


def _case(compliance: float):
    """A UR5 with a 6-D probe, its joints 2-4 bending by ``compliance`` rad per TAU_REF N·m: 300
    training poses (20 µm, 0.05 mrad) and 200 held-out joint vectors."""
    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    q = ur5.sample_joints(300, seed=1)
    true = kincal.perturb(extend(ur5, "compliance", q), seed=3)
    true = true.with_params({n: compliance for n in true.term_names})
    return ur5, true, simulate_poses(true, q, TARGET, 20e-6, 0.05e-3, seed=1), ur5.sample_joints(200, seed=9)


def _error(robot, true, q) -> float:
    return float(np.mean(np.linalg.norm(robot.forward(q) - true.forward(q), axis=1)))


def test_compliance_from_poses():
    ur5, true, obs, q = _case(2e-4)
    geometric = fit_observations(ur5, [obs])
    fit = fit_observations(ur5, [obs], error_model="compliance")
    assert fit.robot.error_model == "compliance"
    assert _error(fit.robot, true, q) < 0.5 * _error(geometric.robot, true, q)
    assert {"j2.compliance", "j3.compliance"} <= set(fit.robot.params.names)  # the joints gravity loads most
    for n in true.term_names:
        if n in fit.robot.params.names:  # the true compliance within 4 σ
            assert abs(fit.robot.params[n] - true.params[n]) < 4 * fit.std[n], n
        else:  # dropped as negative: only a term the data barely see (its true value within 4 σ of the estimate)
            note = next(x for x in fit.notes if x.startswith(n.split(".")[0] + ":"))
            estimate, sigma = float(note.split("(")[1].split()[0]), float(note.split("σ ")[1].split(")")[0])
            assert abs(estimate - true.params[n] / TAU_REF) < 4 * sigma, note
    with pytest.raises(ValueError, match="auto"):
        fit_observations(ur5, [obs], error_model="auto")


def test_negative_compliance_is_dropped():
    ur5, true, obs, q = _case(-3e-4)
    fit = fit_observations(ur5, [obs], error_model="compliance")
    dropped = [n for n in true.term_names if n not in fit.robot.params.names]
    assert dropped and len(fit.notes) == len(dropped) and "came out negative" in fit.notes[0]
    for note in fit.notes:  # the estimate and its σ in rad/(N·m): the true value within 4 σ
        estimate, sigma = float(note.split("(")[1].split()[0]), float(note.split("σ ")[1].split(")")[0])
        assert abs(estimate - (-3e-4 / TAU_REF)) < 4 * sigma, note
    # the same as a fit without those terms from the start
    plain = fit_observations(drop_terms(extend(ur5, "compliance", obs.q), dropped), [obs])
    np.testing.assert_allclose(fit.robot.params.values, plain.robot.params.values, rtol=0, atol=1e-9)


@pytest.mark.slow
def test_command_line_error_model_for_poses(tmp_path, capsys):
    ur5, true, obs, q = _case(2e-4)
    path, cal = tmp_path / "poses.csv", tmp_path / "cal.yaml"
    write_observations(path, obs, ur5, ObservationFormat("pose", length_unit="mm"))
    args = ["calibrate", "ur5", str(path), "--type", "pose", "--tool", "50,20,100mm", "--length-unit", "mm",
            "--std-pos", "0.02mm", "--std-rot", "0.05mrad"]
    assert main([*args, "--error-model", "compliance", "-o", str(cal)]) == 0
    assert "(compliance error model)" in capsys.readouterr().out
    robot = kincal.load_robot(str(cal))
    assert robot.error_model == "compliance"
    assert _error(robot, true, q) < 5e-6 + _error(fit_observations(ur5, [obs], error_model="compliance").robot,
                                                  true, q)
    assert main(["report", str(cal), "-o", str(tmp_path / "r.html")]) == 0
    assert "differs from" not in capsys.readouterr().err  # the record repeats the same fit
    assert main([*args, "--error-model", "auto"]) == 1
    assert "name the model" in capsys.readouterr().err
    assert main([*args, "--payload", "2"]) == 1
    assert "only the gravity terms use it" in capsys.readouterr().err
