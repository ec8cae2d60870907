"""The figures of calibrate/evaluate --plot and the report, as drawn: legends beside the data, never over it."""
import matplotlib
import numpy as np
import pytest
from conftest import DATA, UR5_COLS
from matplotlib.backends.backend_agg import FigureCanvasAgg

import kincal
import kincal.cli
from kincal.identify import refit_frame
from kincal.report import evaluation_figures, figure_set
from kincal.report import figures as F

pytestmark = pytest.mark.slow  # real-data calibrations


def drawn(fig):
    """The figure laid out and drawn (Agg, the report's style); its renderer."""
    canvas = FigureCanvasAgg(fig)
    with matplotlib.rc_context(F.RC):
        canvas.draw()
    return canvas.get_renderer()


def legends(fig) -> list:
    return [*fig.legends, *[ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]]


def plotted(ax) -> np.ndarray:
    """(M, 2) display coordinates of every point, marker and bar corner the axes draws."""
    pts = [ax.transData.transform(line.get_xydata()) for line in ax.get_lines() if len(line.get_xydata())]
    pts += [c.get_offset_transform().transform(c.get_offsets()) for c in ax.collections if len(c.get_offsets())]
    for patch in ax.patches:
        box = patch.get_window_extent()
        pts.append(np.array([[box.x0, box.y0], [box.x1, box.y1], [box.x0, box.y1], [box.x1, box.y0],
                             [(box.x0 + box.x1) / 2, box.y1]]))
    return np.vstack(pts) if pts else np.zeros((0, 2))


def inside(box, pts: np.ndarray) -> np.ndarray:
    """(M,) bool: the display points within the box."""
    return (pts[:, 0] >= box.x0) & (pts[:, 0] <= box.x1) & (pts[:, 1] >= box.y0) & (pts[:, 1] <= box.y1)


def covered(fig) -> int:
    """How many plotted points of the figure's axes lie under one of its legends."""
    renderer = drawn(fig)
    boxes = [leg.get_window_extent(renderer) for leg in legends(fig)]
    return sum(int(inside(box, plotted(ax)).sum()) for ax in fig.axes for box in boxes)


@pytest.fixture(scope="module")
def random():
    return kincal.read_measurements(DATA / "ur5_random.csv", kincal.load_robot("ur5"), UR5_COLS, length_unit="mm",
                                    angle_unit="deg")


def test_legends_cover_no_point_of_the_evaluated_data(random):
    """The nominal UR5 on ur5_random.csv (frame re-fitted): its largest error, 1.229 mm at pose 19, was under the
    per-pose figure's legend (upper right), and the histogram's legend covered the bars at 1.15 mm."""
    model = refit_frame(kincal.load_robot("ur5"), random)
    err = np.linalg.norm(random.xyz - model.forward(random.q), axis=1) * 1e3  # mm, computed here
    assert int(np.argmax(err)) + 1 == 19 and err.max() == pytest.approx(1.2288, abs=1e-4)
    figs = evaluation_figures(model, random)
    for name, fig in figs.items():
        assert covered(fig) == 0, name
    ax = figs["per_pose"].axes[0]
    drawn(figs["per_pose"])
    top = ax.transData.transform([[19.0, err.max()]])
    assert not any(inside(leg.get_window_extent(), top)[0] for leg in legends(figs["per_pose"]))


def test_legends_cover_no_point_of_a_calibration(random):
    """The UR5 grid calibration with ur5_random.csv held out in its frame: the held-out panel's legend hid the
    nominal model's errors of poses 15, 18, 19 and 20 (the largest, 1.10 mm)."""
    ur5 = kincal.load_robot("ur5")
    grid = kincal.read_measurements(DATA / "ur5_grid.csv", ur5, UR5_COLS, length_unit="mm", angle_unit="deg")
    res = kincal.calibrate(ur5, grid, diagnose=False)
    figs = figure_set(res, random, same_frame=True)
    for name, fig in figs.items():
        assert covered(fig) == 0, name
    held = figs["per_pose"].axes[1]
    before = held.get_lines()[0].get_xydata()  # the grey points: the nominal model's errors (mm)
    assert int(np.argmax(before[:, 1])) + 1 == 19 and before[:, 1].max() == pytest.approx(1.096, abs=1e-3)
    words = {name: texts(fig) for name, fig in figs.items()}
    assert "distribution of the error after calibration" in words["histogram"]
    assert words["workspace"][0] == "workspace (the training data's frame): o training, ^ held-out"


def texts(fig) -> list[str]:
    """Every title, suptitle, axis label and legend entry of the figure."""
    out = [fig.get_suptitle()] if fig.get_suptitle() else []
    for ax in fig.axes:
        out += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel()]
    return [t for t in out + [x.get_text() for leg in legends(fig) for x in leg.get_texts()] if t]


def test_one_model_evaluated_is_titled_as_such(random, capsys, tmp_path):
    """evaluate of the nominal UR5, never calibrated: no figure says 'after calibration', the workspace names no
    training data (none is shown), no legend says 'model', and the text names one model, not 'both models'."""
    ur5 = kincal.load_robot("ur5")
    figs = evaluation_figures(refit_frame(ur5, random), random)
    words = {name: texts(fig) for name, fig in figs.items()}
    assert not [t for ts in words.values() for t in ts if "after calibration" in t or "after (" in t]
    assert "distribution of the error of ur5" in words["histogram"]
    assert "error per axis of ur5" in words["per_axis"] and "error of ur5 against each joint" in words["vs_joints"]
    assert words["per_pose"][0] == "held-out poses (20): position error of ur5 per pose"
    assert words["workspace"][0] == "workspace (this file's measurement frame)"  # no outlier, no training
    assert "error of ur5 (mm)" in words["workspace"] and "model" not in words["per_pose"]
    assert kincal.cli.main(["evaluate", "ur5", str(DATA / "ur5_random.csv"), "--length-unit", "mm", "--angle-unit",
                            "deg", "--joint-cols", ",".join(UR5_COLS)]) == 0
    out = capsys.readouterr().out
    assert "both models" not in out and "(frame re-registered to these data, kinematics fixed)" in out
