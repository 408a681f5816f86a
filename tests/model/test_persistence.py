"""Model files: exact round trip and a clear error for every malformed-file case."""

import json

import numpy as np
import pytest

from silpose.model.persistence import ModelFileError, arrays_sha256, load_model, read_header, save_model
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes
from silpose.shared.camera import default_rig


@pytest.fixture(scope="module")
def model_and_data():
    data = make_linear_shapes(120, n_views=4, n_points=10, seed=5)
    model = ShapeStructureModel(2, 3, structure_weight=1.5, views=(0, 2, 3), noise_variance=2e-3, n_init=1,
                                random_state=0, max_iter=30)
    model.fit(data.contours, data.joints, rig=default_rig())
    model.dataset_info_ = {"root": "data/smoke", "manifest_sha256": "ab" * 32}
    return model, data


@pytest.fixture()
def saved(tmp_path, model_and_data):
    model, _ = model_and_data
    return save_model(tmp_path / "m.npz", model)


def _rewrite(path, header_edit=None, array_edit=None, rehash=False):
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    header = json.loads(bytes(data.pop("header")).decode())
    if array_edit:
        array_edit(data)
    if rehash:
        header["arrays_sha256"] = arrays_sha256(data)
    if header_edit:
        header_edit(header)
    np.savez(path, header=np.frombuffer(json.dumps(header).encode(), np.uint8), **data)


def test_exact_round_trip(saved, model_and_data):
    model, data = model_and_data
    loaded = load_model(saved)
    for name in ("weights_", "means_", "components_", "noise_variance_", "lower_bounds_"):
        np.testing.assert_array_equal(getattr(loaded.mixture_, name), np.asarray(getattr(model.mixture_, name)))
    assert loaded.layout_ == model.layout_ and loaded.get_params() == model.get_params()
    assert loaded.rig_.to_dict() == default_rig().to_dict()
    present = np.ones((120, 4), bool)
    present[::3, 2] = False
    a, b = model.infer(data.contours, present), loaded.infer(data.contours, present)
    for field in ("joints", "joints_best", "joint_std", "contours_norm", "responsibilities", "log_marginal"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    np.testing.assert_array_equal(model.score_samples(data.contours, data.joints),
                                  loaded.score_samples(data.contours, data.joints))
    h = read_header(saved)
    assert h["dataset"]["manifest_sha256"] == "ab" * 32 and h["views"] == [0, 2, 3]
    assert h["training"]["n_iter"] == model.mixture_.n_iter_
    assert not list(saved.parent.glob(".*tmp*"))  # temporary file renamed away


def test_other_format_version(saved):
    _rewrite(saved, header_edit=lambda h: h.update(format_version=2))
    with pytest.raises(ModelFileError, match=r"m\.npz: field 'header.format_version' is 2"):
        load_model(saved)


def test_tampered_array(saved):
    def edit(d):
        d["means"][0, 0] += 1e-9
    _rewrite(saved, array_edit=edit)
    with pytest.raises(ModelFileError, match="arrays_sha256.*modified"):
        load_model(saved)


def test_inconsistent_shapes_even_with_a_matching_hash(saved):
    _rewrite(saved, array_edit=lambda d: d.update(means=d["means"][:, :-1].copy()), rehash=True)
    with pytest.raises(ModelFileError, match=r"field 'means' has shape \(2, 116\), expected \(2, 117\)"):
        load_model(saved)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(array_edit=lambda d: d.update(weights=d["weights"] * 2), rehash=True),
         "'weights' must be non-negative and sum to 1"),
        (dict(array_edit=lambda d: d.update(noise_variance=-d["noise_variance"]), rehash=True),
         "'noise_variance' must be > 0"),
        (dict(array_edit=lambda d: d.pop("components"), rehash=True), "field 'components' \\(array\\) is missing"),
        (dict(array_edit=lambda d: d.update(extra=np.zeros(2)), rehash=True), "unexpected fields \\['extra'\\]"),
        (dict(header_edit=lambda h: h.pop("feature_layout")), "'header.feature_layout' is missing"),
        (dict(header_edit=lambda h: h["feature_layout"].pop("n_points")), "missing field 'n_points'"),
        (dict(header_edit=lambda h: h["hyperparameters"].update(n_latent=4)),
         "field 'components' has shape \\(2, 117, 3\\), expected \\(2, 117, 4\\)"),
        (dict(header_edit=lambda h: h.update(n_rig_views=3)), "exceeds n_rig_views 3"),
        (dict(header_edit=lambda h: h["joint_names"].reverse()), "'header.joint_names' differs"),
        (dict(header_edit=lambda h: h["rig"]["cameras"].pop()), "header.rig"),
    ],
)
def test_malformed_fields(saved, kwargs, match):
    _rewrite(saved, **kwargs)
    with pytest.raises(ModelFileError, match=r"m\.npz: .*" + match):
        load_model(saved)


def test_foreign_files(tmp_path):
    txt = tmp_path / "notes.npz"
    txt.write_text("hello")
    with pytest.raises(ModelFileError, match="notes.npz: not a silpose model file"):
        load_model(txt)
    plain = tmp_path / "plain.npz"
    np.savez(plain, a=np.zeros(3))
    with pytest.raises(ModelFileError, match="plain.npz: not a silpose model file \\(field 'header' is missing\\)"):
        load_model(plain)
    other = tmp_path / "other.npz"
    np.savez(other, header=np.frombuffer(b'{"format": "something-else"}', np.uint8))
    with pytest.raises(ModelFileError, match="'header.format' is 'something-else'"):
        load_model(other)
    arr = tmp_path / "arr.npy"
    np.save(arr, np.zeros(3))
    with pytest.raises(ModelFileError, match="arr.npy: not a silpose model file"):
        load_model(arr)
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, header=np.array([{"format": "silpose-model"}], dtype=object))
    with pytest.raises(ModelFileError, match="pickled.npz: not a silpose model file"):
        load_model(pickled)
    with pytest.raises(ModelFileError, match="no such model file"):
        load_model(tmp_path / "absent.npz")


def test_pooled_fits_round_trip_and_are_checked(tmp_path):
    """n_fits > 1: the file holds n_fits x M components and says so; a count that disagrees is refused."""
    data = make_linear_shapes(120, n_views=4, n_points=10, seed=5)
    model = ShapeStructureModel(2, 3, structure_weight=1.5, noise_variance=2e-3, n_init=1, n_fits=3,
                                random_state=4, max_iter=30).fit(data.contours, data.joints, rig=default_rig())
    assert model.mixture_.weights_.shape == (6,)
    single = ShapeStructureModel(2, 3, structure_weight=1.5, noise_variance=2e-3, n_init=1, random_state=5,
                                 max_iter=30).fit(data.contours, data.joints, rig=default_rig())
    np.testing.assert_allclose(model.mixture_.means_[2:4], single.mixture_.means_)  # fit 2 starts from seed 4 + 1
    path = save_model(tmp_path / "pooled.npz", model)
    back = load_model(path)
    assert back.n_fits == 3 and back.hyperparameters() == model.hyperparameters()
    np.testing.assert_array_equal(back.predict(data.contours[:7]), model.predict(data.contours[:7]))
    _rewrite(path, header_edit=lambda h: h["hyperparameters"].update(n_fits=2))
    with pytest.raises(ModelFileError, match="n_components x n_fits says 2 x 2"):
        load_model(path)
    with pytest.raises(ValueError, match="in-memory fit"):
        ShapeStructureModel(2, 3, n_fits=2).fit_shards(None)
