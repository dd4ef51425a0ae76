"""Versioned JSON persistence of models and identification results (issue 9)."""

import json

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl.io import _persistence as persistence
from hammerstein_ctrl.exceptions import ParameterError, UnknownNameError

EMPS_OPT = [3.138764, 0.544501, -0.398365, 0.045066]


def _simulated_sse(model, data):
    return float(np.sum((data.y - model.simulate(data)) ** 2))


def test_emps_round_trip_reproduces_J_exactly(emps_case, tmp_path):
    model = emps_case.structure.model(EMPS_OPT)
    path = tmp_path / "emps.json"
    model.save(path)
    loaded = hc.load_model(path)
    # bit for bit: same coefficients, same simulation, same J (both ways of computing it)
    assert loaded.linear.den[0][0].tolist() == model.linear.den[0][0].tolist()
    assert loaded.params.tolist() == model.params.tolist()
    assert _simulated_sse(loaded, emps_case.data) == _simulated_sse(model, emps_case.data)
    assert emps_case.cost(emps_case.structure.beta(loaded)) == emps_case.cost(np.array(EMPS_OPT))
    assert abs(emps_case.cost(np.array(EMPS_OPT)) - 0.208517) < 1e-6  # the EMPS optimum of the paper's protocol


def test_emps_result_round_trip(emps_case, tmp_path):
    res = hc.identify(emps_case.data, emps_case.structure, method="lm", x0=EMPS_OPT, maxfev=60)
    path = tmp_path / "result.json"
    hc.save_result(res, path)
    saved = hc.load_result(path)
    assert saved.fun == res.fun and saved.nfev == res.nfev and saved.method == "lm"
    assert saved.params == res.params and saved.success == res.success
    assert saved.fit_percent == res.fit_percent and saved.message == res.message
    assert saved.data["dt"] == emps_case.data.dt and saved.data["n_samples"] == 12000
    assert saved.data["name"] == emps_case.data.name and saved.data["output_unit"] == "m"
    assert saved.structure.describe() == emps_case.structure.describe()
    # the loaded model reproduces J on the estimation data to machine precision
    assert emps_case.cost(saved.structure.beta(saved.model)) == emps_case.cost(res.x)
    assert _simulated_sse(saved.model, emps_case.data) == _simulated_sse(res.model, emps_case.data)
    assert abs(_simulated_sse(saved.model, emps_case.data) - res.fun) <= 1e-14 * res.fun
    assert hc.load_model(path).params.tolist() == res.model.params.tolist()


def test_result_keeps_the_optimisers_status_and_reads_version_2_files(emps_case, tmp_path):
    """Schema 3 stores ``status`` (5: the budget ran out first); a version-2 file, which has none, still loads."""
    from hammerstein_ctrl.optimize import BUDGET_EXHAUSTED

    x0 = [3.0, 0.5, -0.4, 0.0]
    res = hc.identify(emps_case.data, emps_case.structure, method="lm", x0=x0, maxfev=12)
    assert res.status == res.optimize_result.status == BUDGET_EXHAUSTED and not res.success
    assert res.to_dict()["status"] == BUDGET_EXHAUSTED
    path = tmp_path / "result.json"
    hc.save_result(res, path)
    doc = json.loads(path.read_text())
    assert doc["schema_version"] == 4 and doc["status"] == BUDGET_EXHAUSTED
    assert hc.load_result(path).status == BUDGET_EXHAUSTED
    old = dict(doc, schema_version=2)
    for key in ("status", "covariance", "dof", "warnings"):
        del old[key]
    path.write_text(json.dumps(old))
    saved = hc.load_result(path)
    assert saved.status is None and saved.fun == res.fun and not saved.success
    assert hc.load_model(path).params.tolist() == res.model.params.tolist()
    for bad, message in ((dict(old, status=5), r"unexpected field\(s\) \['status'\]"),
                         ({k: v for k, v in doc.items() if k != "status"}, r"missing the field\(s\) \['status'\]"),
                         (dict(doc, status="5"), "status must be an integer")):
        path.write_text(json.dumps(bad))
        with pytest.raises(ParameterError, match=message):
            hc.load_result(path)


def test_a_saved_result_keeps_its_covariance_intervals_and_warnings(trs_case, tmp_path):
    """Schema 4: the covariance (aligned with beta), the degrees of freedom and the warnings round-trip; a
    version-3 file, which has none, loads without them."""
    res = hc.identify(trs_case.data, trs_case.structure)
    path = tmp_path / "result.json"
    hc.save_result(res, path)
    saved = hc.load_result(path)
    np.testing.assert_array_equal(saved.covariance, res.covariance)
    assert saved.dof == res.dof and saved.stderr == res.stderr and saved.conf_int(0.9) == res.conf_int(0.9)
    assert saved.warnings == res.warnings and saved.warnings      # TRS: d0 and d1 trade off
    doc = json.loads(path.read_text())
    v3 = {k: v for k, v in doc.items() if k not in ("covariance", "dof", "warnings")}
    path.write_text(json.dumps(dict(v3, schema_version=3)))
    old = hc.load_result(path)
    assert old.covariance is None and old.warnings == []
    with pytest.raises(ParameterError, match="no covariance"):
        _ = old.stderr


@pytest.mark.parametrize("change, message", [
    (lambda d: d.update(covariance=[[1.0]]), "rows of"),
    (lambda d: d["covariance"][0].__setitem__(0, -1.0), "non-negative"),
    (lambda d: d["covariance"][0].__setitem__(1, 123.0), "symmetric"),
    (lambda d: d.update(dof=0), "dof must be a positive integer"),
    (lambda d: d.update(warnings="careful"), "warnings must be a list"),
    (lambda d: d.update(warnings=[3]), r"warnings\[0\] must be a string"),
])
def test_a_damaged_covariance_or_warning_list_is_refused(trs_case, tmp_path, change, message):
    res = hc.identify(trs_case.data, trs_case.structure)
    doc = hc.io.result_to_dict(res)
    change(doc)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ParameterError, match=message):
        hc.load_result(path)


def test_version_2_model_files_still_load(tmp_path):
    model = hc.HammersteinModel(ct.tf([1], [1, 3.138764, 0]), hc.Coulomb(), [0.544501, -0.398365, 0.045066])
    path = tmp_path / "m.json"
    model.save(path)
    doc = json.loads(path.read_text())
    path.write_text(json.dumps(dict(doc, schema_version=2)))
    assert hc.load_model(path).params.tolist() == model.params.tolist()


def test_trs_round_trip_is_bitwise(trs_case, tmp_path):
    model = trs_case.structure.model(trs_case.true_beta)
    hc.save_model(model, tmp_path / "trs.json")
    loaded = hc.load_model(tmp_path / "trs.json")
    np.testing.assert_array_equal(loaded.simulate(trs_case.data), model.simulate(trs_case.data))
    assert loaded.nonlinearity.param_names == ("d0", "d1")


@pytest.mark.parametrize("nl, params", [
    (hc.Polynomial(3), [1.0, -0.2, 0.05]),
    (hc.PiecewiseLinear([-1.0, 0.0, 0.5, 2.0]), [-1.0, 0.0, 0.7, 1.1]),
    (hc.Saturation(), [2.0, 0.7]),
    (hc.DeadZone(), [1.5, 0.2]),
])
def test_family_options_survive(nl, params, tmp_path):
    model = hc.HammersteinModel(ct.tf([1.0, 2.0], [1.0, 3.0, 2.0]), nl, params, name="demo")
    hc.save_model(model, tmp_path / "m.json")
    loaded = hc.load_model(tmp_path / "m.json")
    assert repr(loaded.nonlinearity) == repr(nl) and loaded.name == "demo"
    t = np.arange(200) * 0.01
    u = np.sin(3 * t) * 2
    np.testing.assert_array_equal(loaded.simulate(t, u), model.simulate(t, u))


def _tamper(tmp_path, edit, name="bad.json"):
    model = hc.HammersteinModel(ct.tf([1], [1, 3.138764, 0]), hc.Coulomb(), EMPS_OPT[1:])
    obj = persistence.model_to_dict(model)
    doc = {"format": persistence.MODEL_FORMAT, "schema_version": persistence.SCHEMA_VERSION, "model": obj}
    text = edit(doc)
    path = tmp_path / name
    path.write_text(text if isinstance(text, str) else json.dumps(doc))
    return path


def _set(path_keys, value):
    def edit(doc):
        target = doc
        for k in path_keys[:-1]:
            target = target[k]
        target[path_keys[-1]] = value
    return edit


def _delete(path_keys):
    def edit(doc):
        target = doc
        for k in path_keys[:-1]:
            target = target[k]
        del target[path_keys[-1]]
    return edit


@pytest.mark.parametrize("edit, error, message", [
    (_set(["schema_version"], 99), ParameterError, "unsupported schema_version 99"),
    (_set(["format"], "something/else"), ParameterError, "format is 'something/else'"),
    (_delete(["model", "offset"]), ParameterError, "missing the field(s) ['offset']"),
    (_delete(["model", "input_nonlinearity", "params", "d2"]), ParameterError, "missing the field(s) ['d2']"),
    (_set(["model", "input_nonlinearity", "params", "d1"], "nan"), ParameterError, "params.d1 must be a number"),
    (_set(["model", "input_nonlinearity", "family"], "wavelet"), UnknownNameError, "unknown nonlinearity 'wavelet'"),
    (_set(["model", "linear", "den"], []), ParameterError, "linear.den must be a non-empty list"),
    (_set(["model", "intersample"], "bl"), ParameterError, "intersample must be one of"),
    (_set(["model", "surprise"], 1), ParameterError, "unexpected field(s) ['surprise']"),
])
def test_tampered_files_fail_with_specific_messages(tmp_path, edit, error, message):
    path = _tamper(tmp_path, edit)
    with pytest.raises(error) as info:
        hc.load_model(path)
    assert message in str(info.value)


def test_nan_literal_and_overflow_are_rejected(tmp_path):
    path = _tamper(tmp_path, lambda doc: json.dumps(doc).replace("-0.398365", "NaN"))
    with pytest.raises(ParameterError, match="non-standard JSON constant NaN"):
        hc.load_model(path)
    path = _tamper(tmp_path, lambda doc: json.dumps(doc).replace("-0.398365", "-1e999"))
    with pytest.raises(ParameterError, match=r"params.d1 must be a finite number, got -inf"):
        hc.load_model(path)
    path = _tamper(tmp_path, lambda doc: "{not json")
    with pytest.raises(ParameterError, match="not valid JSON"):
        hc.load_model(path)


def test_custom_nonlinearity_cannot_be_saved(tmp_path):
    model = hc.HammersteinModel(ct.tf([1], [1, 1]), hc.CustomNonlinearity(lambda u, p: p[0] * u, 1), [2.0])
    with pytest.raises(ParameterError, match="custom function is code, not data"):
        hc.save_model(model, tmp_path / "c.json")


def test_non_finite_run_figures_are_valid_json(trs_case, tmp_path):
    res = hc.identify(trs_case.data, trs_case.structure, method="nspsa", x0=trs_case.x0, maxfev=15, seed=0)
    res.fun, res.fit_percent, res.rmse = float("inf"), float("-inf"), float("nan")
    path = tmp_path / "diverged.json"
    hc.save_result(res, path)

    def strict(constant):
        raise AssertionError(f"non-standard constant {constant} in the file")

    doc = json.loads(path.read_text(), parse_constant=strict)
    assert (doc["J"], doc["fit_percent"], doc["rmse"]) == ("inf", "-inf", "nan")
    saved = hc.load_result(path)
    assert saved.fun == np.inf and saved.fit_percent == -np.inf and np.isnan(saved.rmse)
    # in a model field the same strings are refused
    doc["model"]["offset"] = "inf"
    path.write_text(json.dumps(doc))
    with pytest.raises(ParameterError, match="model.offset must be a number"):
        hc.load_result(path)


def test_result_with_inconsistent_beta_is_rejected(trs_case, tmp_path):
    res = hc.identify(trs_case.data, trs_case.structure, method="nspsa", x0=trs_case.x0, maxfev=15, seed=0)
    doc = hc.io.result_to_dict(res)
    doc["beta"][0] += 1.0
    doc["params"]["b0"] += 1.0
    path = tmp_path / "r.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ParameterError, match="the model does not have the parameters beta"):
        hc.load_result(path)


def test_model_settings_are_stored(tmp_path):
    """offset, initial state and intersample are part of the schema."""
    model = hc.HammersteinModel(ct.tf([1], [1, 3.0, 0]), hc.Coulomb(), [0.5, -0.4, 0.05], offset=0.25,
                                initial_state=[0.1, -0.2], intersample="zoh")
    doc = persistence.model_to_dict(model)
    assert (doc["offset"], doc["initial_state"], doc["intersample"]) == (0.25, [0.1, -0.2], "zoh")
    hc.save_model(model, tmp_path / "s.json")
    loaded = hc.load_model(tmp_path / "s.json")
    assert loaded.offset == 0.25 and list(loaded.initial_state) == [0.1, -0.2]
    assert loaded.intersample == "zoh"


def test_wiener_and_hammerstein_wiener_round_trip(tmp_path):
    t = np.arange(0, 5, 0.01)
    u = np.sin(3 * t)
    models = [hc.WienerModel(ct.tf([1], [1, 2.0, 3.0]), hc.Saturation(), [2.0, 0.1], offset=0.5),
              hc.HammersteinWienerModel(ct.tf([1], [1, 1.5]), hc.DeadZone(), [1.0, 0.2], hc.Tanh(), [3.0, 0.7])]
    for model in models:
        hc.save_model(model, tmp_path / "m.json")
        loaded = hc.load_model(tmp_path / "m.json")
        assert type(loaded) is type(model) and loaded.kind == model.kind
        assert np.array_equal(loaded.simulate(t, u), model.simulate(t, u))
    doc = json.loads((tmp_path / "m.json").read_text())
    doc["model"]["kind"] = "wiener"
    (tmp_path / "m.json").write_text(json.dumps(doc))
    with pytest.raises(ParameterError, match="input_nonlinearity must be null in a wiener structure"):
        hc.load_model(tmp_path / "m.json")




# -- hostile files -------------------------------------------------------------------------------------------
def _raw(tmp_path, data: bytes, name="h.json"):
    path = tmp_path / name
    path.write_bytes(data)
    return path


def _doc_text():
    model = hc.HammersteinModel(ct.tf([1], [1, 3.138764, 0]), hc.Coulomb(), EMPS_OPT[1:])
    doc = {"format": persistence.MODEL_FORMAT, "schema_version": persistence.SCHEMA_VERSION,
           "model": persistence.model_to_dict(model)}
    return json.dumps(doc)


@pytest.mark.parametrize("data, message", [
    (b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
    (_doc_text().encode("utf-16"), "not a UTF-8 text file"),
    (_doc_text().encode("utf-32"), "not a UTF-8 text file"),
    (bytes(range(256)) * 10, "not a UTF-8 text file"),
    (b'{"format": "x", ' + _doc_text().encode()[1:], "'format' appears twice"),
    (_doc_text().replace('"schema_version": 4', '"schema_version": ' + "9" * 400).encode(), "400 digits"),
    (_doc_text().replace('"offset": 0.0', '"offset": 1' + "0" * 400).encode(), "401 digits"),
    (_doc_text().replace('"den": [1.0, 3.138764, 0.0]', '"den": [0.0, 0.0]').encode(), "denominator is zero"),
    (_doc_text().replace('"den": [1.0, 3.138764, 0.0]', '"den": [' + ", ".join(["1.0"] * 3001) + "]").encode(),
     "has order 3000; at most 10"),
    (_doc_text().replace('"den": [1.0, 3.138764, 0.0]', '"den": [1.0, 1e308, 0.0]').encode(),
     "beyond the largest magnitude stored"),
    (_doc_text().replace('"schema_version": 4', '"schema_version": true').encode(), "unsupported schema_version"),
    (b"\xef\xbb\xbf" + b"{not json", "not valid JSON"),
])
def test_hostile_model_files_fail_with_one_clear_error(tmp_path, data, message):
    with pytest.raises(ParameterError, match=message):
        hc.load_model(_raw(tmp_path, data))


def test_a_utf8_byte_order_mark_is_tolerated(tmp_path):
    path = _raw(tmp_path, b"\xef\xbb\xbf" + _doc_text().encode())
    assert hc.load_model(path).params.tolist() == list(EMPS_OPT[1:])


@pytest.fixture(scope="module")
def result_doc(trs_case):
    res = hc.identify(trs_case.data, trs_case.structure, method="lm", x0=trs_case.x0, maxfev=200)
    return hc.io.result_to_dict(res)


@pytest.mark.parametrize("key, value, message", [
    (("data", "dt"), -0.01, "dt must be a positive sampling interval"),
    (("data", "dt"), 0.0, "dt must be a positive sampling interval"),
    (("data", "n_samples"), -5, "n_samples must be at least 1"),
    (("data", "n_samples"), True, "n_samples must be an integer"),
    (("data", "intersample"), "cubic", "intersample must be one of"),
    (("data", "name"), 12, "name must be a string"),
    (("nfev",), -1, "nfev must be at least 0"),
    (("nfev",), 2.5, "nfev must be an integer"),
    (("status",), 17, "status must be one of the optimisers' codes"),
    (("success",), 1, "success must be true or false"),
    (("dof",), 0, "dof must be a positive integer"),
    (("dof",), None, "dof is null beside a covariance"),
    (("J",), "1e3", "J must be a number"),
])
def test_a_tampered_result_is_refused_naming_the_field(tmp_path, result_doc, key, value, message):
    doc = json.loads(json.dumps(result_doc))
    target = doc
    for k in key[:-1]:
        target = target[k]
    target[key[-1]] = value
    path = tmp_path / "r.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ParameterError, match=message):
        hc.load_result(path)


def test_saving_to_a_folder_is_a_clear_error(tmp_path):
    model = hc.HammersteinModel(ct.tf([1], [1, 1]), hc.Tanh(), [1.0, 1.0])
    with pytest.raises(hc.HammersteinError, match="is a folder: give a file name"):
        hc.save_model(model, tmp_path)


# -- fuzz: whatever a file holds, loading raises ParameterError/UnknownNameError or returns a valid model ------------
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-10**30, 10**30) | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=20)


def _mutations(doc):
    """Strategy of documents: the valid one with one field (at any depth) replaced by any JSON value, or deleted."""
    paths = []

    def walk(obj, path):
        if isinstance(obj, dict):
            for k, v in obj.items():
                paths.append(path + (k,))
                walk(v, path + (k,))
        elif isinstance(obj, list):
            for i, v in enumerate(obj):
                paths.append(path + (i,))
                walk(v, path + (i,))
    walk(doc, ())

    @st.composite
    def mutated(draw):
        out = json.loads(json.dumps(doc))
        path = draw(st.sampled_from(paths))
        target = out
        for k in path[:-1]:
            target = target[k]
        if draw(st.booleans()) and isinstance(target, dict):
            del target[path[-1]]
        else:
            target[path[-1]] = draw(_JSON)
        return out
    return mutated()


def _load_or_clear_error(path, loader):
    try:
        out = loader(path)
    except (ParameterError, UnknownNameError):
        return None
    return out


@settings(max_examples=150, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(doc=_mutations(json.loads(_doc_text())))
def test_fuzzed_model_files_load_or_fail_clearly(tmp_path_factory, doc):
    path = tmp_path_factory.mktemp("fuzz") / "m.json"
    path.write_text(json.dumps(doc))
    model = _load_or_clear_error(path, hc.load_model)
    if model is not None:       # what loads is a usable model: it simulates a short record to finite numbers
        t = np.arange(0.0, 0.05, 0.01)
        with np.errstate(all="ignore"):
            y = model.simulate(t, np.ones_like(t))
        assert y.shape == t.shape


@settings(max_examples=150, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(data=st.binary(max_size=300) | st.text(max_size=300).map(str.encode))
def test_fuzzed_bytes_never_raise_anything_but_a_clear_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("fuzz") / "m.json"
    path.write_bytes(data)
    for loader in (hc.load_model, hc.load_result, hc.io.load_saved):
        _load_or_clear_error(path, loader)


def test_fuzzed_result_files_load_or_fail_clearly(tmp_path, result_doc):
    @settings(max_examples=100, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
    @given(doc=_mutations(result_doc))
    def check(doc):
        path = tmp_path / "r.json"
        path.write_text(json.dumps(doc))
        _load_or_clear_error(path, hc.load_result)
    check()
