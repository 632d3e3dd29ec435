
import numpy as np
import pytest

from cekm_swarm.errors import ModelFormatError
from cekm_swarm.models.io import load_model, model_provenance, save_model
from cekm_swarm.models.networks import make_network


@pytest.mark.parametrize("name", ["R15", "G9", "D15", "B15"])
def test_round_trip(tmp_path, name):
    net = make_network(name, np.random.default_rng(0))
    path = save_model(tmp_path / f"{name}.npz", net, {"network": name, "steps": 0})
    back = load_model(path)
    assert back.kind == net.kind and back.lattice.size == net.lattice.size
    np.testing.assert_array_equal(back.w, net.w)
    u = np.array([0.4, 0.07])
    np.testing.assert_array_equal(back.command(u), net.command(u))
    assert model_provenance(path)["network"] == name
    assert not list(tmp_path.glob("*.tmp"))  # written atomically


def test_bfn_rule_round_trips(tmp_path):
    net = make_network("B9", np.random.default_rng(0), bfn_rule="paper")
    net.won[:3] = True
    back = load_model(save_model(tmp_path / "b.npz", net))
    assert back.rule == "paper"
    u = np.array([0.4, 0.07])
    np.testing.assert_array_equal(back.command(u), net.command(u))
    data = dict(np.load(tmp_path / "b.npz"))
    del data["bfn_rule"]  # a file from before the rule existed: the rule it was trained with
    np.savez(tmp_path / "old.npz", **data)
    assert load_model(tmp_path / "old.npz").rule == "trained-units"
    data["bfn_rule"] = np.array("other")
    np.savez(tmp_path / "bad.npz", **data)
    with pytest.raises(ModelFormatError, match="bfn_rule"):
        load_model(tmp_path / "bad.npz")


def _write(path, **fields):
    np.savez(path, **{k: np.asarray(v) for k, v in fields.items()})
    return path


def _valid_fields():
    net = make_network("R9", np.random.default_rng(0))
    import json

    from cekm_swarm.models.params import params_to_dict

    return {
        "format": "cekm-model",
        "format_version": 1,
        "kind": "indirect-rls",
        "lattice_size": 9,
        "w": net.w,
        "M": net.M,
        "Rinv": net.Rinv,
        "params": json.dumps(params_to_dict(net.comp, net.learn_p)),
        "provenance": "{}",
    }


@pytest.mark.parametrize("change,field,message", [
    (dict(format="something-else"), "format", "expected 'cekm-model'"),
    (dict(format_version=7), "format_version", "version 7 is not supported"),
    (dict(kind="mlp"), "kind", "unknown network kind"),
    (dict(lattice_size=10), "w", "expected shape (100, 2)"),
    (dict(M=np.zeros((81, 3))), "M", "expected shape (81, 2, 2)"),
    (dict(w=np.full((81, 2), np.nan)), "w", "NaN"),
    (dict(params="{not json"), "params", "unreadable"),
])
def test_bad_fields_are_named(tmp_path, change, field, message):
    fields = _valid_fields()
    fields.update(change)
    path = _write(tmp_path / "bad.npz", **fields)
    with pytest.raises(ModelFormatError) as err:
        load_model(path)
    assert str(path) in str(err.value) and f"field '{field}'" in str(err.value) and message in str(err.value)


def test_missing_field_is_named(tmp_path):
    fields = _valid_fields()
    del fields["Rinv"]
    with pytest.raises(ModelFormatError, match="field 'Rinv': missing"):
        load_model(_write(tmp_path / "m.npz", **fields))


def test_damaged_and_missing_files(tmp_path):
    good = save_model(tmp_path / "good.npz", make_network("G9", np.random.default_rng(0)))
    damaged = tmp_path / "damaged.npz"
    damaged.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(ModelFormatError, match="not a readable"):
        load_model(damaged)
    with pytest.raises(ModelFormatError, match="no such file"):
        load_model(tmp_path / "absent.npz")
    text = tmp_path / "text.npz"
    text.write_text("hello")
    with pytest.raises(ModelFormatError, match="damaged|not a readable"):
        load_model(text)


def test_a_file_that_is_not_npz_is_named_without_numpys_pickle_advice(tmp_path):
    """numpy reads an unknown file as a pickle and advises loading it unsafely; a lone .npy
    array was a TypeError traceback."""
    text = tmp_path / "notmcap.mcap"
    text.write_text("hello\n")
    with pytest.raises(ModelFormatError) as err:
        load_model(text)
    assert str(err.value) == f"{text}: not a readable .npz model file (not an .npz archive)"
    npy = tmp_path / "array.npz"
    with open(npy, "wb") as f:
        np.save(f, np.zeros(3))
    with pytest.raises(ModelFormatError, match=r"\(an .npy array, not an .npz archive\)"):
        load_model(npy)
