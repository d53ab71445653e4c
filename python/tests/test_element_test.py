"""Element tests on the server equal rve_cli's CSV of the same set and seed."""

import subprocess

import numpy as np
import pytest

import rvehub

CASES = [
    ("drained-biaxial", dict(confining=100e3, strain=0.005, rows=20)),
    ("isotropic", dict(confining=50e3, strain=0.002, rows=10)),
    ("oedometer", dict(strain=0.001, rows=10, axis="x")),
    ("undrained-simple-shear", dict(strain=0.002, rows=10)),
    ("cyclic-simple-shear", dict(strain=0.002, amplitude=0.0005, cycles=1, rows=10)),
]

_FLAGS = {"confining": "confining", "strain": "strain", "rows": "rows", "axis": "axis",
          "amplitude": "amplitude", "cycles": "cycles", "inertial_number": "inertial-number"}


def cli_csv(tmp_path, test, material="SET-dense", seed=1, **options):
    out = tmp_path / f"{test}.csv"
    args = [rvehub.find_binary("rve_cli"), "element-test", f"--test={test}",
            f"--material={material}", f"--seed={seed}", f"--out={out}"]
    args += [f"--{_FLAGS[k]}={v!r}" if isinstance(v, float) else f"--{_FLAGS[k]}={v}"
             for k, v in options.items()]
    subprocess.run(args, check=True, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                   stderr=subprocess.PIPE, timeout=300)
    return out


@pytest.mark.parametrize("test,options", CASES, ids=[c[0] for c in CASES])
def test_equals_rve_cli(hub, tmp_path, test, options):
    fractions = []
    res = hub.element_test(test, material="SET-dense", seed=1, progress=fractions.append,
                           **options)
    assert res.template == "SET-dense-seed1" and res.test == test
    assert list(res) == list(rvehub.ELEMENT_TEST_COLUMNS)
    assert res["step"].dtype == np.int64 and res["sxx"].dtype == np.float64
    assert res.rows >= 2 and fractions[-1] == 1.0
    path = cli_csv(tmp_path, test, **options)
    # The same text as rve_cli writes (%.10g), and the same values to that precision.
    assert res.csv_text() == path.read_text()
    ref = rvehub.read_element_test_csv(str(path))
    for c in rvehub.ELEMENT_TEST_COLUMNS:
        printed = np.array(["%.10g" % v for v in res[c]], dtype=np.float64)
        np.testing.assert_array_equal(printed, ref[c], err_msg=c)


def test_signs_are_compression_positive(hub):
    res = hub.element_test("drained-biaxial", confining=100e3, strain=0.005, rows=10)
    # Compression +: the axial stress grows above the confining one.
    assert res["syy"][-1] > res["sxx"][-1] > 0
    np.testing.assert_allclose(res["sxx"], 100e3, rtol=0.02)
    assert res["axial_strain"][-1] > 0.004
    np.testing.assert_allclose(res["p"], (res["sxx"] + res["syy"]) / 2, rtol=1e-12)


def test_on_a_named_template_and_to_csv(hub, template, tmp_path):
    res = hub.element_test("isotropic", template=template, strain=0.002, rows=10)
    out = tmp_path / "x.csv"
    res.to_csv(str(out))
    assert out.read_text() == cli_csv(tmp_path, "isotropic", strain=0.002, rows=10).read_text()
    assert dict(res)["q"] is res["q"]


def test_template_file_and_variants(hub, tmp_path):
    path = str(tmp_path / "t.h5")
    name = rvehub.prepare_template_file(path, "SET-dense", seed=2, particles=100)
    assert name == rvehub.template_name("SET-dense", 2, particles=100) == "SET-dense-seed2-100discs"
    infos = hub.upload_template_file(path)
    assert [t.name for t in infos] == [name] and infos[0].num_particles == 100
    with pytest.raises(rvehub.RveError, match="ALREADY_EXISTS"):
        hub.upload_template_file(path)
    assert rvehub.template_name("SET-dense", 1, pressure=2e6, void_ratio=0.25,
                                rolling_eta=0.02) == "SET-dense-seed1-p2e06Pa-e0.25-eta0.02"
    with pytest.raises(ValueError, match="--void-ratio must lie in"):
        rvehub.prepare_template_file(path, void_ratio=1.5)
    with pytest.raises(rvehub.RveError) as e:
        rvehub.prepare_template_file(path, "no-such-set")
    assert e.value.code.name == "NOT_FOUND"
    assert "unknown parameter set 'no-such-set'" in e.value.message
