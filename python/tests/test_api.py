"""The typed API on a local server: creation, TRIAL and COMMIT, the step
protocol, tangents, per-point status, states, runs and drops."""

import dataclasses

import grpc
import numpy as np
import pytest

import rvehub
from rvehub._proto import pb


def compress_y(n, strain=1e-4):
    f = np.tile(np.eye(3), (n, 1, 1))
    f[:, 1, 1] -= strain
    return f


def test_server_info_and_templates(hub, template):
    info = hub.info()
    assert info.api_version == "rvehub.v1"
    assert info.threads == 1
    assert info.num_templates >= 1
    names = [t.name for t in hub.templates()]
    assert template in names
    t = next(t for t in hub.templates() if t.name == template)
    assert t.num_particles == 400
    assert t.material_name == "SET-dense"
    assert 50e3 < t.mean_pressure < 200e3  # compression +
    # A second prepare of the same name reuses the hosted template.
    assert hub.prepare_template("SET-dense", seed=1) == t


def test_create_trial_commit(hub, template, run_id):
    run = hub.create_run(run_id, template, ids=[3, 1, 2], pressure=100e3)
    np.testing.assert_array_equal(run.ids, [3, 1, 2])
    np.testing.assert_array_equal(run.steps, [0, 0, 0])
    c = run.created
    assert c.failed == 0 and c.ok.all()
    # Isotropic 100 kPa: σxx ≈ σyy ≈ −1e5 Pa (tension +), p ≈ +1e5 Pa.
    np.testing.assert_allclose(c.mean_pressure, 100e3, rtol=0.02)
    np.testing.assert_allclose(c.stress[:, 0, 0], -100e3, rtol=0.05)
    np.testing.assert_array_equal(c.stress[:, 2, 2], 0)

    before = run.states()
    f = compress_y(3)
    trial = run.apply(f, mode="trial", tangent=True)
    assert trial.failed == 0
    np.testing.assert_array_equal(trial.step, [0, 0, 0])  # TRIAL changes nothing
    assert trial.tangent.shape == (3, 3, 3, 3, 3)
    assert np.all(trial.tangent[:, 1, 1, 1, 1] > 1e6)  # Pa
    assert np.all(trial.stress[:, 1, 1] < before.stress[:, 1, 1])  # more compression
    after_trial = run.states()
    np.testing.assert_array_equal(after_trial.stress, before.stress)
    np.testing.assert_array_equal(after_trial.step, before.step)

    commit = run.apply(f)  # mode="commit", step 1
    np.testing.assert_array_equal(commit.step, [1, 1, 1])
    np.testing.assert_array_equal(run.steps, [1, 1, 1])
    assert commit.tangent is None
    # TRIAL and COMMIT of the same increment give the same bits.
    np.testing.assert_array_equal(commit.stress, trial.stress)
    np.testing.assert_array_equal(run.states().stress, commit.stress)
    np.testing.assert_allclose(commit.deformation_gradient[:, 1, 1], 1 - 1e-4)

    # A retried COMMIT of the current step returns the stored result.
    again = run.apply(f, step=1)
    assert again.failed == 0
    np.testing.assert_array_equal(again.stress, commit.stress)
    np.testing.assert_array_equal(run.steps, [1, 1, 1])

    # Step 2 from the handle's own count; a (3, 3) ΔF applies to every id.
    two = run.apply(compress_y(1)[0], ids=[1, 2])
    np.testing.assert_array_equal(two.step, [2, 2])
    np.testing.assert_array_equal(run.steps, [1, 2, 2])
    with pytest.raises(ValueError, match="different committed steps"):
        run.apply(f)


def test_per_point_failures_stay_per_point(hub, template, run_id):
    run = hub.create_run(run_id, template, ids=[0, 1])
    run.apply(compress_y(1)[0], ids=[0])
    # Step 1 again for both: point 0 is at step 1 (FAILED_PRECONDITION unless
    # it is the stored retry, which it is not: another ΔF), point 1 advances.
    res = run.apply(compress_y(2, 2e-4), step=1)
    assert res.failed == 1
    np.testing.assert_array_equal(res.ok, [False, True])
    assert res.code[0] == grpc.StatusCode.FAILED_PRECONDITION.value[0]
    assert "step" in res.message[0]
    assert np.isnan(res.stress[0]).all() and np.isfinite(res.stress[1]).all()
    np.testing.assert_array_equal(res.step, [1, 1])
    with pytest.raises(rvehub.RveError) as e:
        res.check()
    assert e.value.code == grpc.StatusCode.FAILED_PRECONDITION
    assert e.value.ids == [0]
    # An increment the engine refuses (a stretch beyond max_stretch) fails
    # that point alone, and the RVE stays where it was.
    big = compress_y(2, 1e-4)
    big[0, 0, 0] = 2.5
    res = run.apply(big, step=2)
    assert res.code[0] == grpc.StatusCode.INVALID_ARGUMENT.value[0], res.message
    assert res.ok[1]
    np.testing.assert_array_equal(run.steps, [1, 2])


def test_states_unknown_ids_are_per_point(hub, template, run_id):
    run = hub.create_run(run_id, template, ids=[10])
    s = run.states([10, 11], tangent=True)
    np.testing.assert_array_equal(s.code, [0, grpc.StatusCode.NOT_FOUND.value[0]])
    assert np.isfinite(s.tangent[0]).all() and np.isnan(s.tangent[1]).all()


def test_states_carry_every_rve_state_field():
    names = {f.name for f in pb.RveState.DESCRIPTOR.fields}
    fields = {f.name for f in dataclasses.fields(rvehub.States)}
    assert names <= fields, names - fields
    result = {f.name for f in pb.RveResult.DESCRIPTOR.fields} - {"state"}
    assert result <= fields | {"id"}


def test_k0_and_per_point_initial_states(hub, template, run_id):
    run = hub.create_run(run_id, template, ids=[0, 1], vertical_compression=[50e3, 150e3], k0=0.5)
    s = run.created
    np.testing.assert_allclose(-s.stress[:, 1, 1], [50e3, 150e3], rtol=0.05)
    np.testing.assert_allclose(-s.stress[:, 0, 0], [25e3, 75e3], rtol=0.1)
    more = run.create([2], template, pressure=[80e3])
    np.testing.assert_allclose(more.mean_pressure, 80e3, rtol=0.05)
    np.testing.assert_array_equal(run.ids, [0, 1, 2])


def test_runs_handle_and_drop(hub, template, run_id):
    run = hub.create_run(run_id, template, ids=[5, 6, 7])
    run.apply(compress_y(3))
    info = {r.run_id: r for r in hub.runs()}[run_id]
    assert (info.num_rves, info.min_step, info.max_step) == (3, 1, 1)
    again = hub.run(run_id)
    np.testing.assert_array_equal(np.sort(again.ids), [5, 6, 7])
    np.testing.assert_array_equal(again.steps, [1, 1, 1])
    assert run.drop([6]) == 1
    np.testing.assert_array_equal(run.ids, [5, 7])
    assert hub.drop(run_id) == 2
    assert run_id not in {r.run_id for r in hub.runs()}
    with pytest.raises(rvehub.RveError) as e:
        hub.drop(run_id)
    assert e.value.code == grpc.StatusCode.NOT_FOUND


def test_apply_options_pass_through(hub, template, run_id):
    run = hub.create_run(run_id, template, ids=[0])
    plain = run.apply(compress_y(1), mode="trial")
    stress_only = run.apply(compress_y(1), mode="trial", stress_only=True)
    np.testing.assert_array_equal(stress_only.stress, plain.stress)  # the same bits
    assert stress_only.coordination[0] == 0 and not stress_only.fabric_defined[0]
    assert plain.coordination[0] > 3
    relaxed = run.apply(compress_y(1), mode="trial", relax=True, relax_tolerance=1e-3)
    assert relaxed.steps[0] >= plain.steps[0]
