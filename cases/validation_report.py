#!/usr/bin/env python3
"""The validation report: each case's checks (mpm_client's and fem_client's) against its recorded run.

Two commands:

  python3 cases/validation_report.py record RUN_DIR... [--results=cases/results]
      keeps a finished run small in the repository: RUN_DIR/summary.json as
      cases/results/<case>/summary.json, and from RUN_DIR/run.json the run's record
      (program, version, command line, host, start, end, outcome, wall time, final step
      and time; of a resumed run also its earlier chunks' version, command line, times and
      outcome) as cases/results/<case>/record.json.

  python3 cases/validation_report.py report [--results=cases/results] [--out=VALIDATION.md]
      writes VALIDATION.md from the case files' "checks" (cases/FORMAT.md) and the records:
      per paper one table of checks (ours, the reference, the tolerance, the verdict), then
      per case its figure, runtime, date and version of the run; the owner's rulings on the
      open points, each with the checks that carry it. A case without a record says "no
      record yet"; every number of "ours" is read from a recorded summary.json. With
      --check it writes nothing and exits 1 when the file differs from what it would write
      (a hand edit, or a record added without generating the report again).

A check passes as in mpm_client (client_run/checks.h): |ours - reference| <= tolerance
(absolute) or <= tolerance * |reference| (relative), with the reference a number or another
key of the same summary.json. Debian's python3 alone (json, os, argparse).
"""
import argparse
import glob
import json
import math
import os
import shutil
import sys

HERE = os.path.dirname(os.path.abspath(__file__))

PAPERS = {
    "liang-zhao-mpm-dem": "Liang & Zhao, multiscale MPM×DEM (dry granular soil)",
    "liang-zhao-wu-soga-2023": "Liang, Zhao, Wu & Soga 2023, two-phase MPM×DEM (saturated soil)",
    "analytic": "Closed-form solutions",
    "guo-zhao-2014": "Guo & Zhao 2014, implicit FEM×DEM (fem_client)",
    "desrues-et-al": "Desrues et al., FEM×DEM with a local second gradient (fem_client)",
}

# The paper each case reproduces (a reduced -ci case its full case's).
SATURATED = ("consolidation-1d", "cyclic-shaking", "collapse-saturated", "collapse-dry",
             "wave-propagation")


def paper_of(case):
    if case.startswith("fem-biaxial-second-gradient"):
        return "desrues-et-al"
    if case.startswith("fem-"):
        return "guo-zhao-2014"
    if case.startswith("consolidation-crs"):
        return "analytic"
    if case.startswith(SATURATED):
        return "liang-zhao-wu-soga-2023"
    return "liang-zhao-mpm-dem"


# The figure of each full case, in cases/figures/, drawn from the runs cases/README.md
# describes.
FIGURES = {
    "single-element-biaxial": None,
    "biaxial-specimen-medium": "biaxial-meshes-stress-strain.png",
    "biaxial-specimen-c4": "biaxial-meshes-stress-strain.png",
    "biaxial-specimen-m1": "biaxial-meshes-stress-strain.png",
    "biaxial-specimen-m9": "biaxial-meshes-stress-strain.png",
    "biaxial-specimen-f4": "biaxial-f4-stress-strain.png",
    "biaxial-specimen-medium-fast": "biaxial-medium-fast.png",
    "footing-dense": "footing-dense-load-settlement.png",
    "footing-medium": "footing-medium-load-settlement.png",
    "footing-soft": "footing-soft-load-settlement.png",
    "footing-coarse": None,
    "pipe": "pipe-forces.png",
    "pipe-coarse": "pipe-coarse-forces.png",
    "column-collapse-full": "column-collapse-full-fields.png",
    "consolidation-1d": "consolidation-1d.png",
    "cyclic-shaking-dense": "cyclic-shaking-dense-pore-pressure.png",
    "cyclic-shaking-medium": "cyclic-shaking-medium-pore-pressure.png",
    "collapse-saturated-dense": "collapse-saturated-columns.png",
    "collapse-saturated-medium": "collapse-saturated-columns.png",
    "collapse-saturated-loose": "collapse-saturated-columns.png",
    "collapse-dry-medium": "collapse-saturated-columns.png",
    "collapse-saturated-medium-without-f-bar": "collapse-saturated-refinement.png",
    "collapse-dry-medium-without-f-bar": "collapse-saturated-refinement.png",
    "wave-propagation": "wave-propagation.png",
    "fem-single-element": "fem-single-element-stress-strain.png",
    "fem-biaxial-coarse": "fem-biaxial-stress-strain-meshes.png",
    "fem-biaxial-medium": "fem-biaxial-stress-strain-meshes.png",
    "fem-biaxial-fine": "fem-biaxial-stress-strain-meshes.png",
    "fem-biaxial-coarse-q8": "fem-biaxial-stress-strain-meshes.png",
    "fem-biaxial-hexagonal": "fem-biaxial-hexagonal.png",
    "fem-biaxial-second-gradient": "fem-biaxial-second-gradient-bands.png",
    "fem-simple-shear-strain": "fem-simple-shear-strain-loops.png",
    "fem-simple-shear-stress": "fem-simple-shear-stress-loops.png",
}

# The owner's rulings on the points the papers left open, each with the checks (case,
# quantity) that carry it and what the repository does about it.
VERDICTS = [
    ("dense footing N_q", "reproduced",
     "the paper's own N_q = 14.4, within 10 %; Prandtl's value for our φ' reported beside it "
     "(N_q_prandtl), not judged",
     [("footing-dense", "N_q")]),
    ("φ' of a packing", "corrected",
     "the smoothed peak (running mean over 0.5 % axial strain) of the drained biaxial tests at "
     "10–30 kPa, the mean over seeds where several exist (cases/friction_angle.py); the "
     "footing cases' phi_deg (in their summaries) are the nine-seed means: dense 30.19° ± 1.13, "
     "medium 24.24° ± 1.73, soft 18.80° ± 1.32",
     []),
    ("medium and soft footings", "re-read",
     "against Terzaghi's reduced N'_q (eq. 47) with the ultimate load at the knee (two "
     "tangents: N_q_knee) and at d/B = 0.1 (N_q_at_tenth_width), read on the full runs' "
     "load-settlement curves; the knee is where the two tangents meet, above the curve",
     [("footing-medium", "N_q_knee"), ("footing-medium", "N_q_at_tenth_width"),
      ("footing-soft", "N_q_knee"), ("footing-soft", "N_q_at_tenth_width")]),
    ("column collapse d*", "reproduced",
     "the front behind which 98 % of the points lie, within 10 % of 1.8; the farthest linked "
     "point (runout_normalised) reported as an upper bound, since the deposit ends in a sheet "
     "one or two points thick of contact-free RVEs; the dead zone's 35° against the paper's "
     "39° accepted (docs/column-collapse-runout.md)",
     [("column-collapse-full", "runout_normalised_mass98")]),
    ("pipe", "accepted with reason",
     "penetration peak and horizontal force within the seed and mesh spread; the lateral "
     "vertical force about 10 kN/m above the paper's 25; the raw peak (peak_vertical_force_N) "
     "beside the smoothed one",
     [("pipe", "penetration_peak_force_N"), ("pipe", "lateral_horizontal_force_N"),
      ("pipe", "lateral_vertical_force_N")]),
    ("consolidation", "reproduced",
     "3 % of p0 from Tv = 0.04 on (the consolidation summary); at Tv = 0.010 within 5 % of "
     "the solution with the mixture's inertia, read by cases/consolidation_compare.py from "
     "the frames (4.1 % of p0; docs/consolidation-inertia.md)",
     [("consolidation-1d", "pore_pressure_error_max"),
      ("consolidation-1d", "degree_of_consolidation_error_max")]),
    ("cyclic shaking", "correct, then judge",
     "the excess pore pressure ratio with the point's own σ'v0 = γ'z and the current surface "
     "as datum (the shaking summary), at the centre B and the base C; dense: no build-up; "
     "medium: judged against the reduced medium packing's seed spread (B peak 0.05–1.03, "
     "settlement 2.1–23.3 mm; docs/cyclic-shaking-seeds.md)",
     [("cyclic-shaking-dense", "B_excess_ratio_peak"),
      ("cyclic-shaking-dense", "C_excess_ratio_peak"),
      ("cyclic-shaking-dense", "surface_settlement_m"),
      ("cyclic-shaking-medium", "B_excess_ratio_peak"),
      ("cyclic-shaking-medium", "surface_settlement_m")]),
    ("saturated collapse", "reproduced",
     "the paper's scheme (no F-bar) gives a kinetic-energy peak much smaller than the dry "
     "column's (0.61 for the medium packing on the paper's cells); the cases run with F-bar, "
     "and refinement closes the gap (docs/saturated-collapse-refinement.md); shown: the ratio "
     "of two records' `kinetic_energy_peak_J`, saturated over dry, with F-bar (the three "
     "packings) and without it (the paper's scheme, the medium packing); each saturated "
     "column's peak checked against its dry record's as an upper bound",
     [("collapse-saturated-dense", "kinetic_energy_peak_J"),
      ("collapse-saturated-medium", "kinetic_energy_peak_J"),
      ("collapse-saturated-loose", "kinetic_energy_peak_J"),
      ("collapse-saturated-medium-without-f-bar", "kinetic_energy_peak_J")]),
    ("choices the papers leave open", "recorded",
     "the shaking amplitude, the energies of the solid phase only, the pipe's soil density: "
     "cases/REFERENCE.md",
     []),
]


# The rulings judged on two records rather than one summary's check: (point, text of
# the figures) from the recorded summaries.
def saturated_collapse_ratios(results):
    pairs = [(f"collapse-saturated-{packing}", "collapse-dry-medium")
             for packing in ("dense", "medium", "loose")]
    pairs.append(("collapse-saturated-medium-without-f-bar", "collapse-dry-medium-without-f-bar"))
    out = []
    for saturated, dry_case in pairs:
        sat, _ = read_record(results, saturated)
        dry, _ = read_record(results, dry_case)
        peak = (sat or {}).get("kinetic_energy_peak_J")
        dry_peak = (dry or {}).get("kinetic_energy_peak_J")
        if peak is None or not dry_peak:
            out.append(f"{saturated} over {dry_case}: no record yet")
            continue
        out.append(f"{saturated} over {dry_case}: kinetic-energy peak {peak:.0f} / "
                   f"{dry_peak:.0f} J = {peak / dry_peak:.2f} (at "
                   f"{sat.get('kinetic_energy_peak_time_s', float('nan')):.2f} s against "
                   f"{dry.get('kinetic_energy_peak_time_s', float('nan')):.2f} s)")
    return out


TWO_RECORD_FIGURES = {"saturated collapse": saturated_collapse_ratios}


def load_json(path):
    with open(path) as f:
        return json.load(f)


def cases():
    """(name, case document) of every case file, mpm_client's and fem_client's, by name."""
    out = []
    for path in sorted(glob.glob(os.path.join(HERE, "*.json"))):
        name = os.path.basename(path)[:-len(".json")]
        out.append((name, load_json(path)))
    return out


def evaluate(check, summary):
    """(ours, reference, allowed, verdict) of one check; verdict 'pass', 'FAIL' or
    'no record yet' / 'not in summary.json'."""
    if summary is None:
        return None, None, None, "no record yet"
    ours = summary.get(check["quantity"])
    ref = check["reference"]
    if isinstance(ref, str):
        ref = summary.get(ref)
    if not isinstance(ours, (int, float)) or not isinstance(ref, (int, float)):
        return ours, ref, None, "not in summary.json"
    if "relative_tolerance" in check:
        allowed = check["relative_tolerance"] * abs(ref)
    else:
        allowed = check["absolute_tolerance"]
    off = ours - ref
    bound = check.get("bound")
    within = off <= allowed if bound == "upper" else -off <= allowed if bound == "lower" \
        else abs(off) <= allowed
    ok = math.isfinite(ours) and within
    return ours, ref, allowed, "pass" if ok else "FAIL"


def fmt(x):
    if x is None:
        return "–"
    if isinstance(x, float) and x != 0 and (abs(x) >= 1e5 or abs(x) < 1e-3):
        return f"{x:.4g}"
    return f"{x:.4g}" if isinstance(x, float) else str(x)


def tolerance_text(check):
    sign = {"upper": "+", "lower": "−"}.get(check.get("bound"), "±")
    if "relative_tolerance" in check:
        return f"{sign} {100 * check['relative_tolerance']:g} %"
    return f"{sign} {check['absolute_tolerance']:g}"


def reference_text(check, ref):
    side = {"upper": "at most ", "lower": "at least "}.get(check.get("bound"), "")
    if isinstance(check["reference"], str):
        return side + check["reference"] + (f" = {fmt(ref)}" if ref is not None else "")
    return side + fmt(check["reference"])


def read_record(results, case):
    d = os.path.join(results, case)
    summary = os.path.join(d, "summary.json")
    record = os.path.join(d, "record.json")
    if not (os.path.exists(summary) and os.path.exists(record)):
        return None, None
    return load_json(summary), load_json(record)


# What a record keeps of each earlier chunk of a resumed run.
CHUNK_KEYS = ["version", "command_line", "start", "end", "outcome", "wall_s", "final_step",
              "last_checkpoint"]


def chunk_wall(chunk):
    """An earlier chunk's wall time, s: its own, or for a chunk killed before its end (its host
    or session gone) that of its last checkpoint, the work the next chunk continued from; None
    where its run.json has neither."""
    if "wall_s" in chunk:
        return chunk["wall_s"]
    return (chunk.get("last_checkpoint") or {}).get("wall_s")


def wall_text(rec, unit=""):
    """The record's wall time in s, each figure followed by `unit`; a resumed run's adds its
    earlier chunks'. A killed chunk is counted to its last checkpoint, and named; one with no
    wall time at all is named, not counted as 0 s (the record's note may give its time from
    the run's log)."""
    text = f"{rec.get('wall_s', 0):.1f}{unit}"
    earlier = rec.get("earlier_chunks", [])
    walls = [chunk_wall(c) for c in earlier]
    timed = [w for w in walls if w is not None]
    if timed:
        text += (f" + {sum(timed):.1f}{unit} in {len(timed)} earlier "
                 f"chunk{'s' if len(timed) > 1 else ''}")
    cut = sum(1 for c in earlier if "wall_s" not in c and chunk_wall(c) is not None)
    if cut:
        text += f" ({cut} killed, counted to {'its' if cut == 1 else 'their'} last checkpoint)"
    lost = len(earlier) - len(timed)
    if lost:
        text += (f" + {lost} {'earlier ' if not timed else ''}"
                 f"chunk{'s' if lost > 1 else ''} killed with no wall time recorded")
    return text


def record(args):
    for run in args.run_dirs:
        run_json = load_json(os.path.join(run, "run.json"))
        if run_json.get("outcome") != "finished":
            sys.exit(f"{run}: the run did not finish (outcome {run_json.get('outcome')!r})")
        case = run_json["case"]["name"]
        out = os.path.join(args.results, case)
        os.makedirs(out, exist_ok=True)
        if os.path.exists(os.path.join(run, "summary.json")):
            if load_json(os.path.join(run, "summary.json")).get("case") != case:
                sys.exit(f"{run}: summary.json is not {case!r}'s")
            shutil.copyfile(os.path.join(run, "summary.json"), os.path.join(out, "summary.json"))
        else:
            # A case whose summary kind is "none" writes no figures: its record keeps the
            # run's runtime and version alone.
            with open(os.path.join(out, "summary.json"), "w") as f:
                json.dump({"case": case}, f, indent=2)
                f.write("\n")
        keep = ["program", "version", "command_line", "host", "start", "end", "outcome",
                "wall_s", "final_step", "final_time"]
        rec = {k: run_json[k] for k in keep if k in run_json}
        rec["case"] = case
        # A run continued by resume: its run.json keeps the chunks before the last one.
        earlier = [{k: chunk[k] for k in CHUNK_KEYS if k in chunk}
                   for chunk in run_json.get("previous", [])]
        if earlier:
            rec["earlier_chunks"] = earlier
        if args.note:
            rec["note"] = args.note
        with open(os.path.join(out, "record.json"), "w") as f:
            json.dump(rec, f, indent=2, ensure_ascii=False)
            f.write("\n")
        print(f"recorded {case} in {out}")


def cell(text):
    """Free text as one Markdown table cell: its pipes escaped."""
    return str(text).replace("|", "\\|")


def report(args):
    all_cases = cases()
    results_rel = os.path.relpath(args.results, os.path.dirname(os.path.abspath(args.out)))
    figures_rel = os.path.relpath(os.path.join(HERE, "figures"),
                                  os.path.dirname(os.path.abspath(args.out)))
    lines = ["# Validation", "",
             "Generated by `python3 cases/validation_report.py report` from the case files' "
             "`checks` (`cases/FORMAT.md`) and the run records in "
             f"`{os.path.relpath(args.results, os.path.dirname(HERE))}/` (each run's "
             "`summary.json` and `record.json`). Do not edit by hand: record a run "
             "(`validation_report.py record RUN_DIR`) and generate it again. \"ours\" is read "
             "from the recorded `summary.json`; a case without a record says so.", ""]
    recorded = []
    evaluated = {}
    for name, doc in all_cases:
        summary, rec = read_record(args.results, name)
        if rec is not None:
            recorded.append((name, rec))
        evaluated[name] = [(c, evaluate(c, summary)) for c in doc.get("checks", [])]

    lines += ["Generated from these runs:", "",
              "| case | built from | host | start (UTC) | wall time, s | note |",
              "|---|---|---|---|---|---|"]
    for name, rec in recorded:
        lines.append(f"| {name} | version {rec.get('version', '–')} | {rec.get('host', '–')} | "
                     f"{rec.get('start', '–')} | {wall_text(rec)} | "
                     f"{cell(rec.get('note', ''))} |")
    lines.append("")

    for ci in (False, True):
        lines += ["## " + ("Reduced cases (the test suite runs and asserts these)" if ci
                           else "Full cases"), ""]
        for paper, title in PAPERS.items():
            rows = [(n, d) for n, d in all_cases
                    if paper_of(n) == paper and (n.endswith("-ci") == ci)
                    and not (ci and n == "single-element-biaxial")]
            if not ci:
                rows = [(n, d) for n, d in rows if not n.endswith("-ci")]
            if not rows:
                continue
            lines += [f"### {paper}: {title}", "",
                      "| case | quantity | ours | reference | tolerance | verdict | source |",
                      "|---|---|---|---|---|---|---|"]
            for name, doc in rows:
                if not evaluated[name]:
                    where = ("the case's description and cases/README.md" if name.startswith("fem-")
                             else "see the rulings below")
                    lines.append(f"| {name} | – | – | – | – | no machine-readable check | "
                                 f"{where} |")
                for check, (ours, ref, _, verdict) in evaluated[name]:
                    lines.append(f"| {name} | `{check['quantity']}` | {fmt(ours)} | "
                                 f"{reference_text(check, ref)} | {tolerance_text(check)} | "
                                 f"**{verdict}** | {cell(check['source'])} |")
            lines.append("")
            lines += ["| case | runtime (expected, 2 cores) | run: version, wall time, date | "
                      "figure | other figures of the run |", "|---|---|---|---|---|"]
            for name, doc in rows:
                summary, rec = read_record(args.results, name)
                run = "no record yet"
                if rec is not None:
                    run = (f"version {rec.get('version', '–')}, {wall_text(rec, ' s')}, "
                           f"{rec.get('start', '–')[:10]}")
                fig = FIGURES.get(name)
                fig_text = (f"[{fig}]({figures_rel}/{fig})"
                            if fig and os.path.exists(os.path.join(HERE, "figures", fig)) else "–")
                checked = {c["quantity"] for c in doc.get("checks", [])}
                checked |= {c["reference"] for c in doc.get("checks", [])
                            if isinstance(c["reference"], str)}
                others = "–"
                if summary is not None:
                    others = ", ".join(f"{k} {fmt(v)}" for k, v in summary.items()
                                       if k != "case" and k not in checked) or "–"
                lines.append(f"| {name} | {doc.get('expected_runtime_s', 0):g} s | {run} | "
                             f"{fig_text} | {others} |")
            lines.append("")

    lines += ["## The owner's rulings on the open points", "",
              "| point | ruling | reference and rule | checks that carry it |",
              "|---|---|---|---|"]
    for point, verdict, rule, carried in VERDICTS:
        states = []
        for case, quantity in carried:
            for check, (ours, ref, _, v) in evaluated.get(case, []):
                if check["quantity"] == quantity:
                    states.append(f"{case} `{quantity}`: {v}")
        if point in TWO_RECORD_FIGURES:
            states += TWO_RECORD_FIGURES[point](args.results)
        lines.append(f"| {cell(point)} | {cell(verdict)} | {cell(rule)} | "
                     f"{'; '.join(states) if states else 'no summary.json figure'} |")
    lines.append("")
    text = "\n".join(lines)
    failed = sum(1 for v in evaluated.values() for _, e in v if e[3] == "FAIL")
    if args.check:
        current = open(args.out).read() if os.path.exists(args.out) else None
        if current != text:
            print(f"{args.out} is not what the records give: run "
                  "`python3 cases/validation_report.py report`")
            return 1
        print(f"{args.out} is up to date: {len(recorded)} recorded runs, {failed} failed checks")
        return 0
    with open(args.out, "w") as f:
        f.write(text)
    print(f"wrote {args.out}: {len(recorded)} recorded runs, {failed} failed checks")
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    r = sub.add_parser("record", help="keep finished runs' summary and record")
    r.add_argument("run_dirs", nargs="+")
    r.add_argument("--results", default=os.path.join(HERE, "results"))
    r.add_argument("--note", default="", help="a line kept with each record (e.g. the host's "
                   "load while it ran)")
    g = sub.add_parser("report", help="write VALIDATION.md")
    g.add_argument("--results", default=os.path.join(HERE, "results"))
    g.add_argument("--out", default=os.path.join(os.path.dirname(HERE), "VALIDATION.md"))
    g.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 when the file is not what the records give")
    a = ap.parse_args()
    return (record if a.command == "record" else report)(a) or 0


if __name__ == "__main__":
    sys.exit(main())
