import numpy as np
import pytest

from hammerstein_ctrl import DataError, fit_percent, fit_report, nrmse, rmse, sse


def test_metrics_against_hand_computation():
    y = np.array([1.0, 2.0, 3.0, 4.0])
    yhat = np.array([1.0, 2.5, 2.5, 4.0])
    assert sse(y, yhat) == 0.5
    assert rmse(y, yhat) == pytest.approx(np.sqrt(0.125))
    assert nrmse(y, yhat) == pytest.approx(np.sqrt(0.5) / np.sqrt(5.0))
    assert fit_percent(y, yhat) == pytest.approx(100 * (1 - np.sqrt(0.1)))
    assert fit_percent(y, y) == 100.0
    assert fit_percent(y, np.full(4, y.mean())) == pytest.approx(0.0)
    assert set(fit_report(y, yhat)) == {"sse", "rmse", "nrmse", "fit_percent"}


def test_metric_errors():
    with pytest.raises(DataError, match="length mismatch: y has 3 samples but yhat has 2"):
        sse([1, 2, 3], [1, 2])
    with pytest.raises(DataError, match="y is constant"):
        fit_percent([1, 1, 1], [1, 2, 3])
    with pytest.raises(DataError, match="yhat contains 1 non-finite"):
        rmse([1, 2], [1, np.nan])
