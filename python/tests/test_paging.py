"""Listings in pages: Hub.templates() and Hub.runs() follow every page of a
server's listing, here one with the smallest message limit (1 MiB) and more
templates than one reply holds; a server whose page tokens would not move on
is an error, not an endless loop."""

import grpc
import pytest

import rvehub
from rvehub._proto import pb


def long_name(prefix, k):
    """128 bytes, the most a name may have; in k's order."""
    return f"{prefix}-{k:05d}-".ljust(128, "x")


def count_calls(hub, method):
    """Wraps hub._call to count the calls of ``method``: a list of one count."""
    count = [0]
    call = hub._call

    def counting(rpc, request, timeout=None):
        if rpc == method:
            count[0] += 1
        return call(rpc, request, timeout)

    hub._call = counting
    return count


def test_templates_beyond_one_message_come_in_pages():
    with rvehub.local(threads=1, timeout=120, extra_args=["--max-message-mb=1"]) as h:
        first = h.prepare_template("SET-dense", seed=1).name
        run = h.create_run("paging", first, ids=[0])
        packing = run.export()[0].packing
        n = 300  # 4 KiB descriptions: ~1.3 MB in all
        for k in range(n):
            h.upload_template(long_name("t", k), packing, description="d" * 4096)
        pages = count_calls(h, "ListTemplates")
        names = [t.name for t in h.templates()]
        assert pages[0] >= 2
        assert names == sorted(names)
        assert names == [first] + [long_name("t", k) for k in range(n)]  # "S" < "t"
        # Runs page alike; a few fit in one page.
        h.import_(run.export(), run_id="paging-2")
        assert [r.run_id for r in h.runs()] == ["paging", "paging-2"]
        assert h.stop() == 0, open(h.log_path).read()


class FakeHub(rvehub.Hub):
    """A Hub whose ListRuns replies come from a list of pages."""

    def __init__(self, pages):
        super().__init__("127.0.0.1:1")
        self.pages = pages
        self.tokens = []

    def _call(self, rpc, request, timeout=None):
        assert rpc == "ListRuns"
        self.tokens.append(request.page_token)
        runs, token = self.pages[len(self.tokens) - 1]
        return pb.ListRunsResponse(runs=[pb.RunInfo(run_id=r, num_rves=1) for r in runs],
                                   next_page_token=token)


def test_runs_follow_every_page_token():
    h = FakeHub([(["a", "b"], "b"), (["c", "d"], "d"), (["e"], "")])
    assert [r.run_id for r in h.runs()] == ["a", "b", "c", "d", "e"]
    assert h.tokens == ["", "b", "d"]
    h.close()


def test_a_page_token_that_does_not_move_on_is_an_error():
    h = FakeHub([(["a", "b"], "b"), (["b"], "b")])
    with pytest.raises(rvehub.RveError) as e:
        h.runs()
    assert e.value.code == grpc.StatusCode.INTERNAL
    assert "does not follow" in e.value.message
    h.close()
