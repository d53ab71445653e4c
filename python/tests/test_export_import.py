"""Export and Import streams: bit-exact records, continuation on another
server, all-or-nothing imports, packings uploaded as templates."""

import dataclasses

import grpc
import numpy as np
import pytest

import rvehub


def strain_path(n, k):
    f = np.tile(np.eye(3), (n, 1, 1))
    f[:, 1, 1] = 1 - 1e-4 * (1 + 0.1 * k)
    f[:, 0, 1] = 2e-5
    return f


def test_record_round_trip_is_exact(hub, template, run_id):
    run = hub.create_run(run_id, template, ids=[4, 2], pressure=[90e3, 110e3])
    run.apply(strain_path(2, 0))
    records = run.export()
    assert sorted(r.id for r in records) == [2, 4]
    r = records[0]
    assert r.run_id == run_id and r.step == 1
    assert r.last_delta_f.shape == (3, 3)
    p = r.packing
    assert p.cell.shape == (2, 2) and p.num_particles == 400
    assert p.contact_i.dtype == np.uint32 and len(p.contact_i) == len(p.contact_j) > 0
    assert p.material.name == "SET-dense" and p.material.model == "linear"
    assert p.controls.time_step_factor > 0
    # Through the dataclasses and back: the same message, byte for byte.
    exported = hub._call("Export", rvehub.hub.pb.ExportRequest(run_id=run_id, ids=[r.id]))
    raw = next(iter(exported)).records[0]
    assert r.to_proto().SerializeToString() == raw.SerializeToString()
    assert rvehub.Record.from_proto(raw).to_proto() == raw


def test_import_continues_bit_for_bit(hub, template, run_id):
    run = hub.create_run(run_id, template, ids=[0, 1, 2])
    run.apply(strain_path(3, 0))
    records = run.export([0, 2])
    with rvehub.local(threads=1) as other:
        assert other.import_(records) == 2
        moved = other.run(run_id)
        np.testing.assert_array_equal(np.sort(moved.ids), [0, 2])
        np.testing.assert_array_equal(moved.steps, [1, 1])
        for k in (1, 2):
            a = run.apply(strain_path(2, k), ids=[0, 2], tangent=True)
            b = moved.apply(strain_path(2, k), ids=[0, 2], tangent=True)
            np.testing.assert_array_equal(a.stress, b.stress)
            np.testing.assert_array_equal(a.tangent, b.tangent)
            np.testing.assert_array_equal(a.void_ratio, b.void_ratio)
        # A retried COMMIT of the imported step holds too (last_delta_f came along).
        again = moved.apply(strain_path(2, 2), ids=[0, 2], step=3)
        assert again.failed == 0
        assert other.stop() == 0


def test_import_is_all_or_nothing(hub, template, run_id):
    run = hub.create_run(run_id, template, ids=[0, 1])
    records = run.export()
    before = sorted((r.run_id, r.num_rves) for r in hub.runs())
    with pytest.raises(rvehub.RveError) as e:
        hub.import_(records)  # both exist
    assert e.value.code == grpc.StatusCode.ALREADY_EXISTS
    assert sorted((r.run_id, r.num_rves) for r in hub.runs()) == before
    # Into another run: a copy at the same step.
    assert hub.import_(records, run_id=run_id + "-copy") == 2
    copy = hub.run(run_id + "-copy")
    np.testing.assert_array_equal(copy.states().stress, run.states(copy.ids).stress)
    # One malformed record refuses the whole stream (the server names it).
    bad = [dataclasses.replace(r, run_id=run_id + "-bad") for r in records]
    bad[1].packing = dataclasses.replace(bad[1].packing, radius=bad[1].packing.radius[:-1])
    with pytest.raises(rvehub.RveError) as e:
        hub.import_(bad)
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert "nothing imported" in e.value.message
    assert run_id + "-bad" not in {r.run_id for r in hub.runs()}


def test_import_chunks_below_the_message_limit(template, run_id):
    # A 1 MiB message limit: 40 records of ~50 kB need several chunks.
    with rvehub.local(threads=1, extra_args=["--max_message_mb=1"]) as small:
        small.prepare_template("SET-dense", seed=1)
        run = small.create_run(run_id, template, ids=range(40))
        records = run.export()
        assert len(records) == 40
        size = sum(r.to_proto().ByteSize() for r in records)
        assert size > 1 << 20
        assert small.import_(records, run_id="again") == 40
        np.testing.assert_array_equal(small.run("again").states(range(40)).stress,
                                      run.states(range(40)).stress)


def test_upload_a_packing_as_template(hub, template, run_id):
    run = hub.create_run(run_id, template, ids=[0], pressure=200e3)
    rec = run.export()[0]
    info = hub.upload_template(run_id + "-tmpl", rec, description="from an RVE")
    assert info.num_particles == 400 and info.description == "from an RVE"
    np.testing.assert_allclose(info.mean_pressure, 200e3, rtol=0.05)
    with pytest.raises(rvehub.RveError) as e:
        hub.upload_template(run_id + "-tmpl", rec.packing)
    assert e.value.code == grpc.StatusCode.ALREADY_EXISTS
    assert hub.upload_template(run_id + "-tmpl", rec.packing, replace=True).name == info.name
    new = hub.create_run(run_id + "-new", info.name, ids=[0])
    np.testing.assert_allclose(new.created.mean_pressure, 200e3, rtol=0.05)
