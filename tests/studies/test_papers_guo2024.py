"""Guo et al. 2024 reproduced (kincal demo): the default protocol is an exact model, the printed tables are
kincal's own (numbered apart from the paper's) and state their protocol, the comparison is the paper's."""
import dataclasses

import numpy as np
import pytest

from kincal.cli import build_parser
from kincal.studies import guo2024_study

SHORT = {"repeats": 1, "generations": 5, "pool_size": 300}  # the demo's protocol on a short design run (~2 s)


@pytest.fixture(scope="module")
def noisy():
    return guo2024_study(**{**SHORT, "repeats": 2})


@pytest.mark.slow
def test_the_default_protocol_fits_the_truth_without_noise():
    """Errors only on the identifiable parameters: with no noise every design's fit equals the truth
    (training RMS < 1 µm), so no structural misfit decides the ranking of the designs."""
    study = guo2024_study(**SHORT, noise=0.0)
    assert study.protocol == "kincal" and study.noise == 0.0
    for name, rms in study.train_rms.items():
        assert rms < 1e-6, (name, rms)
    drawn = set(study.true_errors)
    assert drawn == set(study.design_params["random"]) and drawn < set(study.separation.names)


@pytest.mark.slow
@pytest.mark.xdist_group("guo2024-noisy")
def test_with_noise_the_fit_is_at_the_noise_level(noisy):
    """15 µm per axis: the 3-D residual RMS is about √3 · 15 µm (less the fitted degrees of freedom),
    not the ~0.15 mm of misfit that errors on the dependent parameters left."""
    for name, rms in noisy.train_rms.items():
        assert 15e-6 < rms < np.sqrt(3) * 15e-6 * 1.2, (name, rms)


@pytest.mark.xdist_group("guo2024-noisy")
def test_the_comparison_is_the_papers_and_the_tables_are_kincals(noisy):
    text = str(noisy)
    assert "'separated-parameter optimised' vs random (the paper's comparison" in text
    assert "'full-parameter optimised' vs random" in text  # printed beside it
    lines = text.splitlines()
    assert not [x for x in lines if x.startswith("Table ")]  # the separation's tables are kincal tables S1, S2, ...
    assert "kincal table S1  GCN of each subdomain of the error model  [analogue: the paper's Table 1]" in lines
    assert any(x.startswith("kincal table S") and "J_d" in x and "the paper's Table 3" in x for x in lines)
    # Table 6: the paper's joint k is kincal's joint k + 1 (its Δd2 is the quill's offset, j3.d)
    assert "the paper's joint k is kincal's joint k + 1" in text
    assert any(x.split()[:2] == ["Δd2", "j3.d"] for x in lines)
    for heading in ("Tables 4-5", "Table 8"):
        line = next(x for x in lines if heading in x and x.startswith("=="))
        assert "kincal protocol: errors on the 16 identifiable kinematic parameters only, 15 µm noise" in line


@pytest.mark.xdist_group("guo2024-noisy")
def test_the_paper_protocol_is_said_to_have_no_noise(noisy):
    paper = dataclasses.replace(noisy, protocol="paper", noise=0.0)
    how = paper.protocol_text()
    assert how.startswith("paper protocol: errors on all ") and ", no noise, " in how
    assert "new errors from random seed k, no noise" in str(paper)
    assert "noise from random seed" not in str(paper)


def test_the_protocol_help_counts_the_parameters():
    sub = next(a for a in build_parser()._actions if a.dest == "command").choices["demo"]
    text = " ".join(sub.format_help().split())
    assert "21 on guo3t2r, 25 on guo3t2r-paper" in text and "all 21 parameters" not in text
