#!/usr/bin/env python3
"""cases/validation_report.py: its verdicts, the figures it reads from two records, and
that the committed VALIDATION.md is what the committed records give.

  /usr/bin/python3 tests/validation_report_test.py [SOURCE_DIR]

Exit status 0 when every check holds; 1 with each failure printed.
"""
import json
import math
import os
import subprocess
import sys
import tempfile

SOURCE = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else
                         os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(SOURCE, "cases"))
import validation_report as vr  # noqa: E402

failures = []


def expect(ok, what):
    if not ok:
        failures.append(what)


# A check passes within its tolerance, relative or absolute, and fails outside it.
rel = {"quantity": "N_q", "reference": 14.4, "relative_tolerance": 0.1}
expect(vr.evaluate(rel, {"N_q": 15.8})[3] == "pass", "15.8 within 10 % of 14.4")
expect(vr.evaluate(rel, {"N_q": 15.9})[3] == "FAIL", "15.9 beyond 10 % of 14.4")
ab = {"quantity": "B", "reference": 0.0, "absolute_tolerance": 0.1}
expect(vr.evaluate(ab, {"B": -0.1})[3] == "pass", "-0.1 within 0 ± 0.1")
expect(vr.evaluate(ab, {"B": math.nan})[3] == "FAIL", "NaN fails")
# The reference may be another key of the same summary.
key = {"quantity": "N_q", "reference": "N_q_reduced", "relative_tolerance": 0.1}
expect(vr.evaluate(key, {"N_q": 4.6, "N_q_reduced": 4.5})[3] == "pass", "by key, pass")
expect(vr.evaluate(key, {"N_q": 8.2, "N_q_reduced": 4.5})[3] == "FAIL", "by key, fail")
# A bound guards one side only.
upper = {"quantity": "E", "reference": 1088.0, "absolute_tolerance": 0.0, "bound": "upper"}
expect(vr.evaluate(upper, {"E": 10.0})[3] == "pass", "far below an upper bound passes")
expect(vr.evaluate(upper, {"E": 1089.0})[3] == "FAIL", "above an upper bound fails")
lower = {"quantity": "d", "reference": 1.76, "relative_tolerance": 0.01, "bound": "lower"}
expect(vr.evaluate(lower, {"d": 9.0})[3] == "pass", "far above a lower bound passes")
expect(vr.evaluate(lower, {"d": 1.745})[3] == "pass", "within 1 % under a lower bound passes")
expect(vr.evaluate(lower, {"d": 1.7})[3] == "FAIL", "beyond 1 % under a lower bound fails")
expect(vr.evaluate(upper, {"E": math.nan})[3] == "FAIL", "NaN fails a bound")
expect(vr.reference_text(upper, 1088.0) == "at most 1088" and vr.tolerance_text(upper) == "+ 0",
       "a bound's text")
expect(vr.evaluate(rel, None)[3] == "no record yet", "no summary")
expect(vr.evaluate(rel, {"other": 1.0})[3] == "not in summary.json", "missing key")

# The saturated collapse is shown as the ratio of two records' kinetic-energy peaks.
with tempfile.TemporaryDirectory() as results:
    def keep(case, summary):
        os.makedirs(os.path.join(results, case))
        for name, doc in (("summary.json", summary), ("record.json", {"case": case})):
            with open(os.path.join(results, case, name), "w") as f:
                json.dump(doc, f)

    keep("collapse-dry-medium", {"case": "collapse-dry-medium", "kinetic_energy_peak_J": 1000.0,
                                 "kinetic_energy_peak_time_s": 0.38})
    keep("collapse-saturated-medium", {"case": "collapse-saturated-medium",
                                       "kinetic_energy_peak_J": 870.0,
                                       "kinetic_energy_peak_time_s": 0.45})
    lines = vr.saturated_collapse_ratios(results)
    expect(len(lines) == 4, f"one line per packing, and the pair without F-bar: {lines}")
    expect(any("collapse-saturated-medium" in l and "870 / 1000 J = 0.87" in l
               and "0.45 s against 0.38 s" in l for l in lines), f"medium's ratio: {lines}")
    expect(any("collapse-saturated-dense" in l and "no record yet" in l for l in lines),
           f"dense has no record: {lines}")

# A resumed run's record keeps its earlier chunks, and the report adds their wall time.
with tempfile.TemporaryDirectory() as tmp:
    run, results = os.path.join(tmp, "run"), os.path.join(tmp, "results")
    os.makedirs(run)
    first = {"version": "v1", "command_line": ["mpm_client", "run", "c.json"], "start": "s1",
             "outcome": "stopped", "wall_s": 100.0, "final_step": 10, "host": "h"}
    last = {"version": "v2", "command_line": ["mpm_client", "resume", "c.h5"], "start": "s2",
            "outcome": "finished", "wall_s": 50.0, "final_step": 20, "host": "h",
            "case": {"name": "collapse-saturated-dense"}, "previous": [first]}
    with open(os.path.join(run, "run.json"), "w") as f:
        json.dump(last, f)
    with open(os.path.join(run, "summary.json"), "w") as f:
        json.dump({"case": "collapse-saturated-dense", "kinetic_energy_peak_J": 900.0}, f)
    vr.record(vr.argparse.Namespace(run_dirs=[run], results=results, note=""))
    with open(os.path.join(results, "collapse-saturated-dense", "record.json")) as f:
        kept = json.load(f)
    expect(kept.get("wall_s") == 50.0 and kept.get("version") == "v2", f"last chunk: {kept}")
    expect(kept.get("earlier_chunks") == [{k: first[k] for k in vr.CHUNK_KEYS if k in first}],
           f"earlier chunks kept: {kept}")
    expect(vr.wall_text(kept) == "50.0 + 100.0 in 1 earlier chunk", vr.wall_text(kept))
    expect(vr.wall_text({"wall_s": 7.0}) == "7.0", "a run in one piece")
    expect(vr.wall_text(kept, " s") == "50.0 s + 100.0 s in 1 earlier chunk",
           vr.wall_text(kept, " s"))
    # A chunk killed before its end has no wall time: named, not added as 0 s.
    killed = {"wall_s": 50.0, "earlier_chunks": [{"outcome": "running", "end": None},
                                                 {"outcome": "stopped", "wall_s": 100.0}]}
    expect(vr.wall_text(killed) == "50.0 + 100.0 in 1 earlier chunk + 1 chunk killed with no "
           "wall time recorded", vr.wall_text(killed))
    # Killed after a checkpoint: counted to it.
    cut = {"wall_s": 50.0, "earlier_chunks": [
        {"outcome": "running", "last_checkpoint": {"step": 20, "wall_s": 30.0}},
        {"outcome": "stopped", "wall_s": 100.0}]}
    expect(vr.wall_text(cut) == "50.0 + 130.0 in 2 earlier chunks (1 killed, counted to its last "
           "checkpoint)", vr.wall_text(cut))
    killed["earlier_chunks"].pop()
    expect(vr.wall_text(killed) == "50.0 + 1 earlier chunk killed with no wall time recorded",
           vr.wall_text(killed))

# Free text keeps its table row whole: a pipe in a note or a source is escaped.
expect(vr.cell("the largest |γ|") == "the largest \\|γ\\|", vr.cell("the largest |γ|"))
with open(os.path.join(SOURCE, "VALIDATION.md")) as f:
    table = []
    for line in list(f) + [""]:
        if line.startswith("|"):
            table.append(line.replace("\\|", "").count("|"))
            continue
        expect(all(n == table[0] for n in table),
               f"a table's rows have its header's cells: {table}")
        table = []

# The committed report is what the committed records give.
check = subprocess.run([sys.executable, os.path.join(SOURCE, "cases", "validation_report.py"),
                        "report", "--check", "--results", os.path.join(SOURCE, "cases", "results"),
                        "--out", os.path.join(SOURCE, "VALIDATION.md")],
                       capture_output=True, text=True)
expect(check.returncode == 0, f"VALIDATION.md out of date: {check.stdout}{check.stderr}")

for f in failures:
    print("FAILED:", f)
print(f"{'FAIL' if failures else 'ok'}: validation_report checks")
sys.exit(1 if failures else 0)
