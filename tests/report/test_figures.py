"""The figures of calibrate/evaluate --plot and the report, as drawn: legends beside the data, never over it."""
import re
import matplotlib
import numpy as np
import pytest
from conftest import DATA, UR5_COLS
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.transforms import Bbox

import kincal
import kincal.cli
from kincal.identify import calibrate_sessions, refit_frame
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
    """(M, 2) display coordinates of every point and marker the axes draws."""
    pts = [ax.transData.transform(line.get_xydata()) for line in ax.get_lines() if len(line.get_xydata())]
    pts += [c.get_offset_transform().transform(c.get_offsets()) for c in ax.collections if len(c.get_offsets())]
    return np.vstack(pts) if pts else np.zeros((0, 2))


def inside(box, pts: np.ndarray) -> np.ndarray:
    """(M,) bool: the display points within the box."""
    return (pts[:, 0] >= box.x0) & (pts[:, 0] <= box.x1) & (pts[:, 1] >= box.y0) & (pts[:, 1] <= box.y1)


def covered(fig) -> int:
    """How many plotted points and bars (boxes, as drawn within their axes) of the figure lie under one of its
    legends."""
    renderer = drawn(fig)
    n = 0
    for box in [leg.get_window_extent(renderer) for leg in legends(fig)]:
        for ax in fig.axes:
            n += int(inside(box, plotted(ax)).sum())
            frame = ax.get_window_extent(renderer)
            drawn_bars = [Bbox.intersection(p.get_window_extent(renderer), frame) for p in ax.patches]
            n += sum(1 for b in drawn_bars if b is not None and b.width > 0 and b.height > 0 and box.overlaps(b))
    return n


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
    # the evaluated file by its name (it said "held-out", also for a calibration's own training file)
    assert words["per_pose"][0] == "ur5_random.csv poses (20): position error of ur5 per pose"
    fig = figs["per_pose"]
    fig.canvas.draw()
    ticks = [t.get_text() for t in fig.axes[0].get_yticklabels(minor=True) + fig.axes[0].get_yticklabels() if
             t.get_text()]
    # the log axis in mm as plain numbers (it read 6×10⁻¹)
    assert "1" in ticks and all(re.fullmatch(r"\d+(\.\d+)?", t) for t in ticks), ticks
    assert words["workspace"][0] == "workspace (this file's measurement frame)"  # no outlier, no training
    assert "error of ur5 (mm)" in words["workspace"] and "model" not in words["per_pose"]
    assert kincal.cli.main(["evaluate", "ur5", str(DATA / "ur5_random.csv"), "--length-unit", "mm", "--angle-unit",
                            "deg", "--joint-cols", ",".join(UR5_COLS)]) == 0
    out = capsys.readouterr().out
    assert "both models" not in out and "(frame re-registered to these data, kinematics fixed)" in out


ETA = {  # kincal demo's η (%) of its first repetition, random and separated-parameter designs (its table)
    "random": {"j1.theta": 99.98, "j1.d": 99.65, "j1.a": 98.92, "j1.alpha": 100.0, "j2.d": 97.87, "j2.a": 99.18,
               "j4.a": 99.09, "j5.d": 99.13},
    "separated-parameter optimised": {"j1.theta": 99.96, "j1.d": 98.93, "j1.a": 99.03, "j1.alpha": 99.98,
                                      "j2.d": 99.53, "j2.a": 99.40, "j4.a": 97.02, "j5.d": 99.69}}


def inside_of(outer, inner) -> bool:
    return outer.x0 <= inner.x0 and inner.x1 <= outer.x1 and outer.y0 <= inner.y0 and inner.y1 <= outer.y1


def test_demo_eta_axis_follows_the_values_and_its_title_fits():
    """η of 97-100 % on an axis of -100..110 % differ by 1.5 % of its height; the title (one line) was cut at
    both edges of the figure."""
    from kincal.report.study_figures import eta_bars

    names = list(ETA["random"])
    fig = eta_bars(ETA, names, {"j2.d"})
    renderer = drawn(fig)
    low, high = fig.axes[0].get_ylim()
    values = [v for d in ETA.values() for v in d.values()]
    assert low < min(values) - 0.1 and high >= 100.0 and high - low < 5.0  # 97.02 .. 100 fill the axis
    assert (99.96 - 97.87) / (high - low) > 0.4  # the two designs' j2.d differ by > 40 % of the axis
    whole = fig.bbox
    assert inside_of(whole, fig.axes[0].title.get_window_extent(renderer))
    assert covered(fig) == 0


def test_demo_validation_summary_labels_inside_and_legend_clear():
    """Fig. 13 of the demo: the bars' value labels end inside the axes (the 25.3 mm one ran into the frame) and
    the legend covers no bar (it covered the std e bar before calibration)."""
    from kincal.report.study_figures import validation_summary

    rng = np.random.default_rng(1)
    e = rng.normal(-11.7, 7.05, 60)  # e (mm) before calibration as the demo's: mean -11.7, std 7.05, max 25.3
    e[np.argmax(np.abs(e))] = -25.3
    errors = {"before calibration": np.repeat(e[:, None], 3, axis=1) * 1e-3,
              "random": rng.normal(0.0, 2e-6, (60, 3)), "full-parameter optimised": rng.normal(0.0, 4e-6, (60, 3)),
              "separated-parameter optimised": rng.normal(0.0, 3e-6, (60, 3))}
    top = max(np.abs(e.mean(axis=1)).max() for e in errors.values()) * 1e3  # the largest bar, |e| max (mm)
    for note in ((), ("first repetition; a protocol",)):
        fig = validation_summary(errors, *note)
        renderer = drawn(fig)
        ax = fig.axes[0]
        frame = ax.get_window_extent(renderer)
        assert ax.get_ylim()[1] > top
        clear = 3.0 * fig.dpi / 72.0  # 3 pt (the 25.3 ended 1.6 px from the frame: touching it)
        for label in ax.texts:
            box = label.get_window_extent(renderer)
            assert inside_of(frame, box) and frame.y1 - box.y1 > clear, label.get_text()
        assert covered(fig) == 0


def test_workspace_names_a_few_outliers_inside_and_lists_the_rest():
    """The UR5 grid read with joints 5 and 6 swapped: 18 outliers, whose 'row ...' labels stacked illegibly and
    ran beyond the axes. Now the three largest errors are named, inside their axes, no two names overlap, and the
    caption lists every outlier, largest first."""
    ur5 = kincal.load_robot("ur5")
    cols = ["joint_1", "joint_2", "joint_3", "joint_4", "joint_6", "joint_5"]
    grid = kincal.read_measurements(DATA / "ur5_grid.csv", ur5, cols, length_unit="mm", angle_unit="deg")
    res = kincal.calibrate(ur5, grid, diagnose=False)
    error = np.linalg.norm(grid.xyz - res.robot.forward(grid.q), axis=1)  # computed here
    out = np.flatnonzero(res.pose_z > res.outlier_z)
    ranked = [f"row {r}" for r in grid.rows[out[np.argsort(-error[out], kind="stable")]]]
    assert len(out) > 10
    fig = figure_set(res)["workspace"]
    renderer = drawn(fig)
    panels = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert len(panels) == 3
    for ax in panels:
        names = [t for t in ax.texts if t.get_text().startswith("row")]
        boxes = [t.get_window_extent(renderer) for t in names]
        frame = ax.get_window_extent(renderer)
        assert 1 <= len(names) <= 3 and all(inside_of(frame, b) for b in boxes)
        assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])
        shown = {n.strip() for t in names for n in t.get_text().replace("rows ", "row ").split(",")}
        assert {n if n.startswith("row") else f"row {n}" for n in shown} == set(ranked[:3])
    caption = fig.get_supxlabel().replace("\n", " ")
    assert caption.endswith(", ".join(ranked)) and f"red circles: {len(out)} outliers" in fig.get_suptitle()


def test_joints_are_drawn_in_the_units_they_are_read_in():
    """The Jugglebot's legs, read in motor revolutions (0.09-3.97 rev, its README), were drawn as 200-1400 'deg'
    against the error; a UR5's joints stay in deg."""
    from conftest import shared_dataset

    table = np.genfromtxt(shared_dataset("stewart_jugglebot") / "S1.csv", delimiter=",", names=True)
    legs = np.column_stack([table[f"leg{i}"] for i in range(1, 7)])  # rev, as written
    xyz = np.column_stack([table["x"], table["y"], table["z"]]) * 1e-3
    hexapod = kincal.load_robot("hexapod")
    s = F.PoseSet("training", np.arange(2, len(legs) + 2), legs * 2.0 * np.pi, xyz, None, np.full_like(xyz, 1e-4),
                  np.zeros(len(legs), bool))
    panels = F.pose_figures([s], hexapod)["vs_joints"].axes
    assert [ax.get_xlabel() for ax in panels] == [f"leg{i} (rev)" for i in range(1, 7)]
    for j, ax in enumerate(panels):
        np.testing.assert_allclose(ax.get_lines()[0].get_xdata(), legs[:, j], rtol=1e-12)
    assert 0.09 <= legs.min() and legs.max() <= 3.98
    ur5 = kincal.load_robot("ur5")
    q = ur5.sample_joints(5, seed=1)
    s = F.PoseSet("training", np.arange(5), q, ur5.forward(q), None, np.full((5, 3), 1e-4), np.zeros(5, bool))
    panels = F.pose_figures([s], ur5)["vs_joints"].axes
    assert panels[0].get_xlabel() == "j1 (deg)"
    np.testing.assert_allclose(panels[0].get_lines()[0].get_xdata(), np.degrees(q[:, 0]), rtol=1e-12)


def test_sensitivity_plot_says_per_which_unit_and_shows_equal_curves():
    """sensitivity --plot's axes said 'mm' for every parameter, though an angle's is per mrad; j1.d (a length
    along the base z axis) moves the point by exactly (0, 0, 1) mm per mm, and its Δx line hid under Δy."""
    from kincal.analysis import sensitivity

    ur5 = kincal.load_robot("ur5")
    fig = sensitivity(ur5, ur5.sample_joints(10, seed=2), names=["j1.d", "j2.theta"]).figure()
    d, theta = fig.axes[:2]
    assert d.get_ylabel() == "Δ (mm per mm)" and theta.get_ylabel() == "Δ (mm per mrad)"
    lines = d.get_lines()
    np.testing.assert_allclose([li.get_ydata() for li in lines], [[0.0] * 10, [0.0] * 10, [1.0] * 10], atol=1e-9)
    styles = {(li.get_marker(), li.get_linestyle(), li.get_markerfacecolor() == "none") for li in lines}
    assert len(styles) == 3  # Δx drawn over Δy is still seen
    assert lines[0].get_markersize() > lines[1].get_markersize() and lines[0].get_markerfacecolor() == "none"
    assert covered(fig) == 0


def test_the_before_legend_says_how_the_nominal_model_was_registered():
    """With --base fixed the "before" model keeps the frame as given: the per-pose legend said "frame and target
    point registered" all the same, unlike the CLI and the report's table (before_registration's words)."""
    ur5 = kincal.load_robot("ur5")
    meas = kincal.simulate(kincal.perturb(ur5, seed=1).with_params({"base.x": 0.0}), ur5.sample_joints(40, seed=2),
                           15e-6, seed=3)
    for base, words in (("fixed", "target point registered, frame as given (--base fixed)"),
                        ("estimate", "frame and target point registered")):
        res = kincal.calibrate(ur5, meas, base=base, diagnose=False)
        assert res.before_registration() == words
        legend = texts(figure_set(res)["per_pose"])
        assert f"before (nominal model, {words})" in legend, legend


def figure_svg(html: str, name: str) -> str:
    """The SVG of the report's figure ``name`` (its ``<figure id="fig-<name>">``)."""
    return re.search(rf'<figure id="fig-{name}">(.*?)</figure>', html, re.S).group(1)


def circled(svg: str) -> list[int]:
    """The red rings of each "outliers" group of an SVG figure (one group per axes that circles some)."""
    return [part.split('<g id="', 1)[0].count("<use") for part in svg.split('<g id="outliers">')[1:]]


def test_outliers_are_circled_in_every_error_figure(ur5):
    """docs/howto/report.md says outliers are circled in the error figures, but only the workspace circled them
    (the UR5 grid with j4/j5 swapped: 15 outliers, none marked per pose or per joint): 4 poses moved 3 mm are the
    report's outliers, and each is ringed once per pose and once in each of the 6 joint panels."""
    true = kincal.perturb(ur5, seed=4)
    meas = kincal.simulate(true, ur5.sample_joints(120, seed=5), 20e-6, seed=6)
    moved = np.array([7, 30, 64, 101])
    xyz = meas.xyz.copy()
    xyz[moved] += np.array([3e-3, -2e-3, 1e-3])
    res = kincal.calibrate(ur5, kincal.Measurements(meas.q, xyz, meas.joint_names, "moved.csv"), diagnose=False)
    report = kincal.build_report(res)
    assert report.data["outliers"] == meas.rows[moved].tolist()
    assert circled(figure_svg(report.html, "per_pose")) == [4]
    assert circled(figure_svg(report.html, "vs_joints")) == [4] * 6
    assert sum(circled(figure_svg(report.html, "workspace"))) == 4 * 3


def test_every_session_has_its_own_colour(ur5):
    """Two training sessions and a held-out one: three colours in the per-axis boxes and the histogram's bars (the
    two training sessions of ur5s.html shared one blue, told apart by nothing)."""
    true = kincal.perturb(ur5, seed=7)
    a, b, c = (kincal.simulate(true, ur5.sample_joints(n, seed=s), 20e-6, seed=s) for n, s in ((60, 1), (50, 2), (20, 3)))
    res = calibrate_sessions(ur5, [kincal.Measurements(m.q, m.xyz, m.joint_names, f"{k}.csv")
                                          for k, m in (("a", a), ("b", b))], diagnose=False)
    html = kincal.build_report(res, kincal.Measurements(c.q, c.xyz, c.joint_names, "c.csv")).html
    boxes = re.findall(r"fill: (#[0-9a-f]{6}); opacity: 0\.5", figure_svg(html, "per_axis"))[:9]  # then the legend's
    assert len(set(boxes)) == 3 and boxes[:3] == boxes[3:6] == boxes[6:]  # x, y, z: same order
    bars = re.findall(r"fill: (#[0-9a-f]{6}); opacity: 0\.6", figure_svg(html, "histogram"))
    assert set(bars) == set(boxes) and F.COLOURS["before"] not in boxes
