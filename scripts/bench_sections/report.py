"""The readable table printed at the end of a benchmark run (the JSON has everything; this is a digest)."""

from __future__ import annotations

import math
from typing import Any

Row = tuple[str, str]


def timing(entry: Any, unit: str = "s", scale: float = 1.0) -> str:
    """``median unit [min …, p95 …, max …; n runs]``, or the skip reason, or the plain value."""
    if isinstance(entry, dict) and entry.get("median") is not None:
        extra = f", p95 {entry['p95'] * scale:.4g}" if "p95" in entry else ""
        return (f"{entry['median'] * scale:.4g} {unit}  [min {entry['min'] * scale:.4g}{extra}, "
                f"max {entry['max'] * scale:.4g}; n={entry['runs']}]")
    if isinstance(entry, dict) and "skipped" in entry:
        return f"skipped: {entry['skipped']}"
    return "n/a" if entry is None else str(entry)


def _ratio(value: float | None, fmt: str = ".3g") -> str:
    return "n/a" if value is None else format(value, fmt)


def _primitives(p: dict[str, Any]) -> tuple[str, list[Row]]:
    rows = [("FK all bodies, CasADi", timing(p["forward_kinematics_casadi_us"], "µs")),
            ("FK all bodies, pinocchio", timing(p["forward_kinematics_pinocchio_us"], "µs")),
            ("momentum map + J*, CasADi", timing(p["momentum_map_and_jstar_casadi_us"], "µs")),
            ("centroidal map, pinocchio", timing(p["centroidal_map_pinocchio_us"], "µs")),
            (f"collision sweep ({p['collision_pairs']} pairs), NLP engine", timing(p["collision_sweep_us"], "µs")),
            ("collision sweep, NLP engine, 23 via points", timing(p["collision_sweep_23_points_us"], "µs")),
            ("collision sweep, verify's engine, 1000 samples", timing(p["collision_verify_1000_samples_s"])),
            (f"verify one plan ({p['verify_plan']['plan_samples']} samples)", timing(p["verify_plan_s"]))]
    shapes = p.get("nlp_jacobian_shapes")
    if shapes:  # a bench.json written before the NLP Jacobians were measured has no such rows
        for nlp in ("approach", "stabilization"):
            rows.append((f"{nlp} NLP Jacobian {shapes[nlp][0]} × {shapes[nlp][1]}",
                         timing(p[f"{nlp}_jacobian_ms"], "ms")))
    return "primitives", rows


def _query(q: dict[str, Any]) -> tuple[str, list[Row]]:
    r = q["refine"]
    after = r["fraction_feasible_after_refine"]
    rows = [("lookup + interpolation", timing(q["lookup_interpolate_ms"], "ms")),
            ("simulate", timing(q["simulate_s"])),
            ("verify", timing(q["verify_s"])),
            ("query total (no refine)", timing(q["query_total_s"])),
            ("feasible from interpolation", f"{q['fraction_feasible_interpolation']:.0%} of {q['states']}"),
            ("refine", timing(r["refine_s"]) if r.get("refine_s") else f"skipped: {r.get('skipped')}"),
            ("feasible after refine", "n/a" if after is None else f"{after:.0%}"),
            ("query process peak RSS / wall", f"{q['peak_memory_query_process_mib']:.0f} MiB / "
                                             f"{q['query_process_wall_s']:.1f} s")]
    return f"query ({q['table']}, {q['states']} states)", rows


def _build(b: dict[str, Any]) -> tuple[str, list[Row]]:
    rows = []
    for key in ("loky_j1", "loky_j2", "dask_2_workers"):
        e = b[key]
        rows.append((f"{key} ({b['points']} points)", f"{e['points_per_hour']:.4g} points/h" if e.get("points_per_hour")
                     else timing(e)))
    er = b["estimated_real"]
    rows += [("scaling efficiency -j 2 / dask", f"{_ratio(b['scaling_efficiency_j2'])} / "
                                                f"{_ratio(b['scaling_efficiency_dask'])} "
                                                f"(layer limit {b['ideal_speedup_j2'] / 2:.3g})"),
             ("harness overhead per point", f"{b['harness_overhead_per_point_s']:.3g} s"),
             ("real planner (golden solve times)", timing(er) if "skipped" in er else
              f"{er['points_per_hour_1_core']:.3g} points/h on 1 core, {er['points_per_hour_2_cores']:.3g} on 2")]
    return f"build (fake solver, {b['fake_point_s']:g} s/point)", rows


def _planner(p: dict[str, Any]) -> tuple[str, list[Row]]:
    rows = []
    for name in ("scenario_I", "scenario_II"):
        for variant, e in p[name].items():
            label = f"{name} {variant}"
            if "skipped" in e:
                rows.append((label, f"skipped: {e['skipped']}"))
                continue
            rows += [(f"{label} {key[:-2]}", timing(e[key])) for key in ("approach_s", "tracking_s",
                                                                          "stabilization_s", "total_s")]
            it = e["ipopt_iterations"]
            rows.append((f"{label} IPOPT iterations / feasible", f"approach {it['approach']['median']:.0f}, "
                         f"stabilization {it['stabilization']['median']:.0f} / {e['feasible']}"))
    return "planner (whole plans, default state)", rows


def _baseline(b: dict[str, Any]) -> tuple[str, list[Row]]:
    rows = _comparison_rows(b, "")
    if "ipopt_exact" in b.get("paper_costs", {}):
        rows += _comparison_rows(b["paper_costs"], "paper costs: ")
    p = b["problem"]
    return f"baseline (scenario II approach NLP: {p['variables']} variables, {p['constraints']} constraints)", rows


def _comparison_rows(b: dict[str, Any], prefix: str) -> list[Row]:
    rows = []
    for key, label in (("ipopt_exact", "IPOPT, exact derivatives"), ("slsqp_finite_difference", "SLSQP, FD")):
        e = b[key]
        rows.append((prefix + label, f"{e['time_s']:.3g} s, {e['iterations']} it, f = {e['objective']:.4g}, "
                                     f"max viol {e['max_violation']:.2g}, "
                                     f"{'ok' if e['success'] else 'not converged'} ({e['status']})"))
    ratio = b["time_ratio_slsqp_over_ipopt"]
    rows.append((prefix + "time ratio SLSQP / IPOPT", f"{ratio:.3g}" if ratio is not None else b["not_comparable"]))
    return rows


def _runs(entry: dict[str, Any]) -> str:
    """``3/5 feasible on time; wall p50 …, p95 … s; reasons …`` of one kind's plans or queries."""
    if entry.get("runs") is None:
        return f"skipped: {entry.get('skipped')}"
    wall = entry["wall_s"]
    kinds = ", ".join(f"{k} {v}" for k, v in entry["failures_by_kind"].items()) or "none"
    cut = f" ({entry['cut_by_the_budget']} cut short by the budget)" if entry["cut_by_the_budget"] else ""
    edge = f"; {entry['failures_at_box_edge']} refused on the box's edge" if entry.get("failures_at_box_edge") else ""
    return (f"{entry['feasible_on_time']}/{entry['states']} feasible on time; wall p50 {wall['median']:.1f}, "
            f"p95 {wall['p95']:.1f}, max {wall['max']:.1f} s; failures by kind: {kinds}{cut}{edge}"
            f"{_by_variant(entry.get('failures_planned_by_variant'))}{_reach_edge(entry.get('reach_edge'))}")


def _by_variant(planned: dict[str, int] | None) -> str:
    """``; the variant plans 5/7 failures (no grasp held 4, braking 1)`` (empty when none was planned again)."""
    if not planned:
        return ""
    kinds = {k: v for k, v in planned.items() if k != "checked"}
    detail = f" ({', '.join(f'{k} {v}' for k, v in kinds.items())})" if kinds else ""
    return f"; the variant plans {sum(kinds.values())}/{planned['checked']} failures{detail}"


def _reach_edge(edge: dict[str, Any] | None) -> str:
    """``; reach: feasible plans ≥ 0.24 m inside it, 9/10 failures nearer its edge`` (empty without slacks)."""
    if not edge or not edge["failures"]:
        return ""
    inside = "no feasible plan" if edge["feasible_nearest_m"] is None else \
        f"feasible plans {-edge['feasible_nearest_m']:.2f} m or more inside it"
    return f"; reach: {inside}, {edge['failures_nearer_the_edge']}/{edge['failures']} failures nearer its edge"


def _coverage(c: dict[str, Any]) -> tuple[str, list[Row]]:
    rows = [(f"{part} {kind}", _runs(c[part][kind])) for part in ("plans", "queries")
            for kind in c["plans"]]
    for name, bar in c["bars"].items():
        verdict = "n/a" if bar["met"] is None else "met" if bar["met"] else "NOT met"
        op = "≤" if bar["at_most"] else "≥"
        value = "n/a" if bar["value"] is None else format(bar["value"], ".3g")
        rows.append((f"bar {name}", f"{value} ({op} {bar['bar']:g}): {verdict}"
                                    f"{'' if bar['enough_states'] else ' (fewer than 20 states per kind)'}"))
    variant = f", scenario variant {c['variant']}" if c.get("variant") else ""
    variant += f", failures planned again with the {c['variant_check']} variant" if c.get("variant_check") else ""
    return (f"coverage ({c['states_per_kind']} states per kind, budget {c['budget_s']:g} s, {c['jobs']} at a time"
            f"{variant})", rows)


def _optimal(o: dict[str, Any]) -> tuple[str, list[Row]]:
    if o.get("runs") is None:
        return "optimal", [("skipped", str(o.get("skipped")))]
    g = o["cost_gap"]
    fmt = {k: "n/a" if v is None else format(v, ".3g") for k, v in {**g["absolute"], **{
        f"rel_{k}": v for k, v in g["relative"].items()}}.items()}
    rows = [("feasible / without re-solve", f"{o['fraction_feasible']:.0%} / "
             f"{o['fraction_feasible_without_resolve']:.0%} of {o['states']} (sources {o['sources']})"),
            ("query latency", timing(o["latency_s"])),
            ("offline optimum wall", f"{timing(o['optimum_wall_s'])}; {o['optima_feasible']} feasible"),
            ("cost gap query − optimum", f"p50 {fmt['p50']}, p95 {fmt['p95']}, max {fmt['max']} (relative p50 "
                                         f"{fmt['rel_p50']}, p95 {fmt['rel_p95']}; {g['compared']} compared)")]
    for name, bar in o["bars"].items():
        verdict = "n/a" if bar["met"] is None else "met" if bar["met"] else "NOT met"
        value = "n/a" if bar["value"] is None else format(bar["value"], ".3g")
        rows.append((f"bar {name}", f"{value} ({'≤' if bar['at_most'] else '≥'} {bar['bar']:g}): {verdict}"
                                    f"{'' if bar['enough_states'] else ' (fewer than 30 states)'}"))
    return f"optimal ({o['table']}, {o['scenario']})", rows


def _reach(r: dict[str, Any]) -> tuple[str, list[Row]]:
    rows = [(f"{kind} {name}", f"{e['out_of_reach']}/{e['states']} out of reach, {e.get('proven', 0)} of them proven"
                               f"{_least_offsets(e.get('proven_least_offset_m'))}")
            for kind, entry in r.items() if isinstance(entry, dict) and kind not in ("what_ifs",)
            for name, e in entry.items()]
    return f"reach ({r['states_per_kind']} states per kind, the scan of meeting times only)", rows


def _least_offsets(offsets: list[float | None] | None) -> str:
    """``; the chaser would have to wait at least 1.14–2.00 m from its station`` for the proven states to come within
    reach at all (``, 1 within reach at no base offset`` for those none brings; empty without a proven state)."""
    if not offsets:
        return ""
    finite = [x for x in offsets if x is not None and math.isfinite(x)]  # inf in memory, null once written
    parts = [f"the chaser would have to wait at least {min(finite):.2f}–{max(finite):.2f} m from its station"
             ] if finite else []
    never = len(offsets) - len(finite)
    return "; " + ", ".join([*parts, *([f"{never} within reach at no base offset"] if never else [])])


UNITS = {"largest_attitude_deg": "° attitude", "largest_rate_deg_s": "°/s rate", "largest_spin_axis_deg": "° spin axis"}


def _carry(r: dict[str, Any]) -> tuple[str, list[Row]]:
    rows: list[Row] = []
    for kind, entry in r.items():
        if not (isinstance(entry, dict) and "steps" in entry):
            continue
        carries = ", ".join(f"{entry[key]} {UNITS[key]}" for key in entry if key.startswith("largest_"))
        rows.append((f"{kind}", f"{entry['feasible_plans']}/{entry['states']} cold plans feasible; carried ≥ "
                                f"{r['carry_bar']:g} up to {carries}"))
        for step, d in entry["steps"].items():
            value = "n/a" if d["as_is"] is None else f"as is {d['as_is']:.2f}, repaired {d['repaired']:.2f}"
            rows.append((f"  {step}", f"{value} of {d['plans']} plans"))
    return f"carry ({r['states_per_kind']} states per kind: a plan re-verified at displaced states)", rows


SECTIONS = {"primitives": _primitives, "query": _query, "build": _build, "planner": _planner,
            "baseline": _baseline, "coverage": _coverage, "optimal": _optimal, "reach": _reach, "carry": _carry}


def print_report(result: dict[str, Any]) -> None:
    """Print the digest table of a benchmark result to stdout."""
    m = result["machine"]
    print(f"lutgen bench — {m['mode']}{' (trim)' if m['trim'] else ''}; {m['cpu_count']} CPUs ({m['cpu_model']}), "
          f"Python {m['python']}, load {m['load_average_start']} → {m['load_average_end']}")
    sections = []
    for name, digest in SECTIONS.items():
        if name not in result:  # a partial run (--only) into a new file
            continue
        data = result[name]
        sections.append((name, [("FAILED", data["error"])]) if "error" in data else digest(data))
    width = max(len(label) for _, rows in sections for label, _ in rows)
    for title, rows in sections:
        print(title)
        for label, value in rows:
            print(f"  {label:<{width}}  {value}")
    if "wall_s" in result:
        print(f"wall time {result['wall_s']:.0f} s")
