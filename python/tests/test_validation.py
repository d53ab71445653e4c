"""Bad input raises a clear Python error (ValueError/TypeError before
sending, RveError with the server's code otherwise) and changes nothing:
the server's full state (every record, bit for bit, and its runs) is read
before and after."""

import math

import grpc
import numpy as np
import pytest

import rvehub


@pytest.fixture
def run(hub, template, run_id):
    r = hub.create_run(run_id, template, ids=[0, 1, 2])
    f = np.tile(np.eye(3), (3, 1, 1))
    f[:, 1, 1] = 1 - 1e-4
    r.apply(f)
    yield r
    hub.drop(run_id)  # each test sees its own run only


def snapshot(hub):
    """Every RVE of every run, serialised, with its run list."""
    runs = sorted((r.run_id, r.num_rves, r.min_step, r.max_step) for r in hub.runs())
    records = {}
    for run_id, *_ in runs:
        for rec in hub.export(run_id):
            records[(run_id, rec.id)] = rec.to_proto().SerializeToString()
    return runs, records, sorted(t.name for t in hub.templates())


def identity(n):
    return np.tile(np.eye(3), (n, 1, 1))


def bad_nan(n):
    f = identity(n)
    f[1, 0, 1] = math.nan
    return f


def bad_inf(n):
    f = identity(n)
    f[2, 1, 1] = math.inf
    return f


def out_of_plane(n):
    f = identity(n)
    f[0, 0, 2] = 1e-3
    return f


def negative_det(n):
    f = identity(n)
    f[1, 0, 0] = -1
    return f


PYTHON_ERRORS = [
    ("wrong shape", lambda r: r.apply(np.ones((3, 2, 2))), ValueError, r"shape \(3, 3, 3\)"),
    ("wrong count", lambda r: r.apply(identity(2)), ValueError, r"shape \(3, 3, 3\)"),
    ("flat", lambda r: r.apply(np.ones(27)), ValueError, "shape"),
    ("NaN", lambda r: r.apply(bad_nan(3)), ValueError, r"delta_f\[1\] \(id 1\) is not finite"),
    ("inf", lambda r: r.apply(bad_inf(3)), ValueError, r"delta_f\[2\] \(id 2\) is not finite"),
    ("not numbers", lambda r: r.apply([["a"] * 3] * 3), TypeError, "array of numbers"),
    ("out of plane", lambda r: r.apply(out_of_plane(3)), ValueError, "not plane strain"),
    ("det <= 0", lambda r: r.apply(negative_det(3)), ValueError, "det ΔF = -1.0 must be > 0"),
    ("mode", lambda r: r.apply(identity(3), mode="Commit"), ValueError, "mode must be"),
    ("duplicate ids", lambda r: r.apply(identity(2), ids=[1, 1]), ValueError, "distinct"),
    ("2-D ids", lambda r: r.apply(identity(2), ids=[[1, 2]]), ValueError, "1-D"),
    ("fractional ids", lambda r: r.apply(identity(1), ids=[1.5]), ValueError, "integers"),
    ("empty ids", lambda r: r.apply(np.zeros((0, 3, 3)), ids=[]), ValueError, "must not be empty"),
    ("step 0", lambda r: r.apply(identity(3), step=0), ValueError, "step must be"),
    ("NaN option", lambda r: r.apply(identity(3), duration=math.nan), ValueError, "duration"),
    ("states ids", lambda r: r.states([[0]]), ValueError, "1-D"),
    ("create: bad name", lambda r: r.hub.create_run("a b", "t", [0]), ValueError, "run id"),
    ("create: NaN pressure", lambda r: r.create([9], "SET-dense-seed1", pressure=math.nan),
     ValueError, "pressure must be finite"),
    ("create: pressure count", lambda r: r.create([8, 9], "SET-dense-seed1", pressure=[1e5]),
     ValueError, r"shape \(2,\)"),
    ("create: k0 alone", lambda r: r.create([9], "SET-dense-seed1", k0=0.5), ValueError,
     "both vertical_compression and k0"),
    ("element test: name", lambda r: r.hub.element_test("triaxial"), ValueError,
     "test must be one of"),
    ("element test: zero", lambda r: r.hub.element_test(confining=0), ValueError,
     "confining must be > 0"),
    ("element test: cyclic option", lambda r: r.hub.element_test(cycles=3), ValueError,
     "cyclic-simple-shear only"),
    ("element test: template and seed",
     lambda r: r.hub.element_test(template="SET-dense-seed1", seed=2), ValueError,
     "does not apply with template="),
    ("import nothing", lambda r: r.hub.import_([]), ValueError, "at least one record"),
    ("import wrong type", lambda r: r.hub.import_([1]), TypeError, "rvehub.Record"),
]


@pytest.mark.parametrize("what,call,error,match", PYTHON_ERRORS, ids=[p[0] for p in PYTHON_ERRORS])
def test_refused_before_sending(hub, run, what, call, error, match):
    before = snapshot(hub)
    with pytest.raises(error, match=match):
        call(run)
    assert snapshot(hub) == before


def _unknown_run_apply(r):
    rvehub.Run(r.hub, "no-such-run").apply(identity(1), ids=[0])


SERVER_ERRORS = [
    ("unknown run", _unknown_run_apply, grpc.StatusCode.NOT_FOUND, 'unknown run "no-such-run"'),
    ("unknown id", lambda r: r.apply(identity(2), ids=[0, 99]), grpc.StatusCode.NOT_FOUND,
     "no material points 99"),
    ("unknown run handle", lambda r: r.hub.run("no-such-run"), grpc.StatusCode.NOT_FOUND,
     "unknown run"),
    ("export unknown run", lambda r: r.hub.export("no-such-run"), grpc.StatusCode.NOT_FOUND,
     "unknown run"),
    ("option out of range", lambda r: r.apply(identity(3), max_inertial_number=5),
     grpc.StatusCode.INVALID_ARGUMENT, "max_inertial_number"),
    ("relax steps out of range", lambda r: r.apply(identity(3), relax_max_steps=10**8),
     grpc.StatusCode.INVALID_ARGUMENT, "relax_max_steps"),
    ("duplicate create", lambda r: r.create([2, 3], "SET-dense-seed1"),
     grpc.StatusCode.ALREADY_EXISTS, ""),
    ("unknown template", lambda r: r.create([7], "no-such-template"), grpc.StatusCode.NOT_FOUND,
     "no-such-template"),
    ("pressure out of range", lambda r: r.create([7], "SET-dense-seed1", pressure=-5.0),
     grpc.StatusCode.INVALID_ARGUMENT, "pressure"),
    ("element test unknown template",
     lambda r: r.hub.element_test(template="nope", strain=0.001), grpc.StatusCode.NOT_FOUND,
     'unknown template "nope"'),
    ("element test strain", lambda r: r.hub.element_test(strain=0.7),
     grpc.StatusCode.INVALID_ARGUMENT, "max_strain"),
]


@pytest.mark.parametrize("what,call,code,match", SERVER_ERRORS, ids=[p[0] for p in SERVER_ERRORS])
def test_refused_by_the_server(hub, run, what, call, code, match):
    before = snapshot(hub)
    steps = run.steps.copy()
    with pytest.raises(rvehub.RveError) as e:
        call(run)
    assert e.value.code == code, str(e.value)
    assert match in e.value.message
    assert e.value.target == hub.target and e.value.rpc
    assert str(e.value).startswith(code.name + ": ")
    assert snapshot(hub) == before
    np.testing.assert_array_equal(run.steps, steps)


def test_oversized_batch_is_refused_whole(template, run_id):
    with rvehub.local(threads=1, extra_args=["--max_batch=2"]) as small:
        small.prepare_template("SET-dense", seed=1)
        with pytest.raises(rvehub.RveError) as e:
            small.create_run(run_id, template, ids=[0, 1, 2])
        assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
        run = small.create_run(run_id, template, ids=[0, 1])
        run.create([2], template)
        before = snapshot(small)
        with pytest.raises(rvehub.RveError) as e:
            run.apply(identity(3))
        assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
        assert snapshot(small) == before
