"""Prediction uncertainty of a calibrated model, and the guard against extrapolation.

With the parameter covariance C (K × K, from the fit) the model's predicted position at joint values
q has the covariance J C Jᵀ (J: the 3 × K position Jacobian of the fitted parameters), so its 3-D
standard deviation is σ(q) = sqrt(trace(J C Jᵀ)). Where the calibration poses constrained the model,
σ(q) stays near its median over those poses (they themselves reach about 1.8× it on real data); far
from them it grows. A pose with σ(q) above ``EXTRAPOLATION_RATIO`` (2.5) times the training median
lies where the data did not constrain the model: its prediction is an extrapolation, and the more
flexible the error model, the less it should be trusted there.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ..models.robot import Robot
from ..models.yaml_io import read_section

EXTRAPOLATION_RATIO = 2.5


@dataclass(frozen=True, eq=False)
class ModelUncertainty:
    """Covariance (K, K) of the fitted ``names`` (SI) and the median predicted σ at the training poses (m)."""

    names: tuple[str, ...]
    covariance: np.ndarray
    training_median: float

    @classmethod
    def from_fit(cls, robot: Robot, names, covariance: np.ndarray, q_train: np.ndarray) -> "ModelUncertainty":
        unc = cls(tuple(names), np.asarray(covariance, dtype=float), 0.0)
        return cls(unc.names, unc.covariance, float(np.median(unc.sigma(robot, q_train))))

    def sigma(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        """(N,) 3-D standard deviation (m) of the predicted position at joint values q (N, n)."""
        J = robot.param_jacobian(robot.check_q(q))[:, :, robot.params.indices(self.names)]
        var = np.einsum("nak,kl,nal->n", J, self.covariance, J)
        return np.sqrt(np.maximum(var, 0.0))

    def extrapolated(self, sigma: np.ndarray) -> np.ndarray:
        """(N,) bool: σ above EXTRAPOLATION_RATIO times the training median."""
        return sigma > EXTRAPOLATION_RATIO * self.training_median

    def to_dict(self) -> dict:
        return {"parameters": list(self.names), "covariance": self.covariance.tolist(),
                "training_median_sigma": self.training_median}

    @classmethod
    def from_dict(cls, data: dict, label: str = "calibration") -> "ModelUncertainty":
        try:
            names = tuple(str(n) for n in data["parameters"])
            cov = np.array(data["covariance"], dtype=float)
            med = float(data["training_median_sigma"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelError(f"{label}: the 'calibration' section is incomplete or malformed ({exc}); "
                             f"calibrate again or remove the section") from None
        if cov.shape != (len(names), len(names)) or not np.all(np.isfinite(cov)) or not np.isfinite(med):
            raise ModelError(f"{label}: the 'calibration' covariance must be a finite {len(names)}x{len(names)} "
                             f"matrix; calibrate again or remove the section")
        return cls(names, cov, med)


def extrapolation_warning(rows: np.ndarray, sigma: np.ndarray, unc: ModelUncertainty) -> str | None:
    """A warning naming the rows whose predicted σ says the model extrapolates there, or None."""
    bad = unc.extrapolated(sigma)
    if not bad.any():
        return None
    shown = ", ".join(str(int(r)) for r in rows[bad][:10]) + (f" and {bad.sum() - 10} more" if bad.sum() > 10 else "")
    return (f"{int(bad.sum())} pose(s) lie where the calibration data did not constrain the model (predicted σ up to "
            f"{sigma[bad].max() / unc.training_median:.1f}x the training median {unc.training_median * 1e3:.4f} mm, "
            f"limit {EXTRAPOLATION_RATIO:g}x): row(s) {shown}; measure calibration poses there too")


def load_uncertainty(name_or_path) -> ModelUncertainty | None:
    """The uncertainty saved with a calibrated robot file (its ``calibration:`` section), or None."""
    section = read_section(name_or_path, "calibration")
    if section is None:
        return None
    if not isinstance(section, dict):
        raise ModelError(f"{name_or_path}: the 'calibration' section must be a mapping")
    return ModelUncertainty.from_dict(section, str(name_or_path))
