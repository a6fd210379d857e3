#!/usr/bin/env python3
"""Writes docs/results.md from the measurements in docs/results/data/ (standard library only).

  scripts/results.py            write the page
  scripts/results.py --check    exit 1 if the committed page differs from what the data give

The data come from scripts/results.sh, which runs the benchmarks and evaluation programs; each
row of the page is one claim: what, target, value (median, spread, runs), status, command.
"""
import argparse
import csv
import json
import math
import os
import statistics
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "docs", "results", "data")
PAGE = os.path.join(ROOT, "docs", "results.md")

MET, NOT_MET, NO_TARGET = "met", "**not met**", "no target"


class Page:
    def __init__(self, data_dir):
        self.data_dir = data_dir
        self.rows = []        # (group, (what, target, value, status, command))
        self.group = ""
        self.sections = []    # (group, title, text, table): detail tables under a group
        self.commands = {}  # name -> command line as run
        self.loads = {}     # name -> load average when it started
        path = os.path.join(data_dir, "commands.tsv")
        if os.path.exists(path):
            for line in open(path, encoding="utf-8"):
                fields = line.rstrip("\n").split("\t")
                if len(fields) == 3:  # name, load average, command
                    self.commands[fields[0]] = fields[2]
                    self.loads[fields[0]] = float(fields[1])
                elif len(fields) == 2:  # name, command
                    self.commands[fields[0]] = fields[1]

    def load(self, name):
        path = os.path.join(self.data_dir, name)
        if not os.path.exists(path):
            return None
        with open(path, encoding="utf-8") as f:
            try:
                return json.load(f)
            except json.JSONDecodeError as e:
                sys.exit(f"results.py: {path}: not valid JSON ({e})")

    def command(self, name, sections=None):
        """The command as a user types it to see the figure; the options that write the data
        files (which scripts/results.sh adds) are left out, and for bench-render only the named
        sections are kept (results.sh runs them all in one process)."""
        words = self.commands.get(name, "").split()
        if sections and words and words[0].endswith("bench-render"):
            rest = [w for w in words[1:]
                    if not w.isalpha() and not (w[0].isalpha() and w.replace("-", "").isalpha())]
            words = [words[0]] + sections.split() + rest
        shown, i = [], 0
        while i < len(words):
            if words[i].startswith("--benchmark_out"):
                i += 1
            elif (words[i] in ("--json", "--csv") and i + 1 < len(words)
                  and words[i + 1].startswith("docs/results/data/")):
                i += 2
            else:
                shown.append(words[i])
                i += 1
        return "`" + " ".join(shown) + "`" if shown else "(see `scripts/results.sh`)"

    def section(self, title, text, table):
        self.sections.append((self.group, title, text, table))

    def row(self, what, target, value, status, command):
        self.rows.append((self.group, (what, target, value, status, command)))


# --- numbers -----------------------------------------------------------------------------------

def fmt(x, digits):
    return f"{x:.{digits}f}".replace("-", "−")


def spread(values, digits=2, unit="", scale=1.0):
    """'median (min-max, n runs)' of a list of numbers."""
    v = sorted(x * scale for x in values)
    med = statistics.median(v)
    if len(v) == 1:
        return f"{fmt(med, digits)}{unit} (1 run)"
    return f"{fmt(med, digits)}{unit} ({fmt(v[0], digits)}–{fmt(v[-1], digits)}, {len(v)} runs)"


def ratios(a_runs, b_runs):
    """Ratios a/b: paired run by run where both lists are as long (frames taken in turn), else
    every a against every b."""
    if len(a_runs) == len(b_runs) and len(a_runs) > 1:
        return [a / b for a, b in zip(a_runs, b_runs)]
    return [a / b for a in a_runs for b in b_runs]


def status(ok):
    return MET if ok else NOT_MET


def gbench_runs(doc, run_name, field):
    """Every repetition's value of one Google Benchmark run (iterations, not aggregates)."""
    return [b[field] for b in doc["benchmarks"]
            if b.get("run_type", "iteration") == "iteration"
            and b.get("run_name", b["name"]) == run_name]


def gbench_find(doc, name):
    """The run name of benchmark `name` (exactly, or with arguments: name/...), if it ran."""
    for b in doc["benchmarks"]:
        run = b.get("run_name", b["name"])
        if run == name or run.startswith(name + "/"):
            return run
    return None


def terrain_db(p):
    """terrain_db_tiles.json and terrain_db_build.json (scripts/bench-terrain-db.sh): the tiled
    terrain database's tile size and codec (read rates, file size, frame footprint) and the
    streaming builder's throughput and peak memory."""
    p.group = "Terrain database"
    doc = p.load("terrain_db_build.json")
    if doc:
        cmd = "`" + doc["command"] + "`"
        for r in doc["runs"]:
            n = r["width"]
            rss = r["peak_rss_bytes"] / 2**20
            p.row(f"Streaming builder, synthetic {n}² (tile {r['tile']}, codec {r['codec']}): "
                  "throughput (wall; per CPU-second), peak resident memory, file",
                  "peak memory ≤ 1 GiB at any size",
                  f"{fmt(r['samples_per_second'] / 1e6, 2)} M samples/s "
                  f"({fmt(r['width'] * r['height'] / r['cpu_seconds'] / 1e6, 2)} M per CPU-s; "
                  f"{fmt(r['seconds'], 0)} s); peak RSS {fmt(rss, 0)} MiB; "
                  f"{fmt(r['file_bytes'] / 1e9, 2)} GB",
                  status(rss <= 1024),
                  ("`" + r["command"] + "`") if "command" in r else cmd.replace("SIZE", str(n)))
    doc = p.load("terrain_db_tiles.json")
    if doc:
        cmd = p.command("terrain_db_tiles") if "terrain_db_tiles" in p.commands else \
            "`bench-tiles --size 4096 --runs 5`"
        lines = ["| tile | codec | file MB | cold tiles/s | cold MB/s | warm tiles/s | warm MB/s "
                 "| frame footprint |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
        for c in doc["configs"]:
            lines.append(
                f"| {c['tile']} | {c['codec']} | {fmt(c['file_bytes'] / 1e6, 1)} | "
                f"{spread(c['cold_tiles_per_s']['runs'], 0)} | "
                f"{spread(c['cold_mb_per_s']['runs'], 0)} | "
                f"{spread(c['warm_tiles_per_s']['runs'], 0)} | "
                f"{spread(c['warm_mb_per_s']['runs'], 0)} | "
                f"{fmt(c['footprint_mb'], 1)} MB in {fmt(c['footprint_tiles'], 0)} tiles |")
        p.section("Tile size and codec",
                  f"Synthetic {doc['size']}² map; every level-0 tile read by {doc['threads']} "
                  "threads (pread, CRC-32, decode), cold (file dropped from the page cache) and "
                  "warm; frame footprint: decoded bytes of the tiles a 720 x 486 (+32 px margins), "
                  "50° frame needs with every level, mean over a 16-pose sweep. Command: " + cmd,
                  "\n".join(lines))
        chosen = [c for c in doc["configs"] if c["tile"] == 64 and c["codec"] == "none"]
        if chosen:
            c = chosen[0]
            ms = [c["footprint_mb"] / v * 1e3 for v in c["cold_mb_per_s"]["runs"]]
            p.row("Tile reads at the chosen tile size 64, no compression: level-0 tiles per "
                  "second cold; time to read a whole frame footprint cold",
                  "footprint ≤ 100 ms (prefetch hides a few frames)",
                  f"{spread(c['cold_tiles_per_s']['runs'], 0)} tiles/s; "
                  f"{spread(ms, 0, ' ms')} for {fmt(c['footprint_mb'], 1)} MB",
                  status(statistics.median(ms) <= 100), cmd)


def paged_flight(p):
    """paged_flight_SIZE.json (scripts/bench-paged-flight.sh): wall-clock flights over a
    synthetic database far larger than --cache-mb, paged by the renderer, one per image size;
    and the cost of paging, the same 4096² flight paged and loaded whole (shown once, from the
    largest map's run)."""
    p.group = "Terrain database"
    docs = [d for d in (p.load(f"paged_flight_{n}.json") for n in (16384, 65536)) if d]
    for doc in docs:
        cmd = "`" + doc["command"] + "`"
        n, mb = doc["size"], doc["cache_mb"]
        # The runs of one image size and placing budget together (REPEATS runs each), and the
        # same flight over a 4096² map in memory flown in turn with them.
        groups = {}
        for b in doc["flights"] + doc.get("flights_full_detail", []):
            key = (b["width"], b["height"], b.get("place_budget_ms"))
            groups.setdefault(key, []).append(b)
        whole = {}
        for b in doc.get("whole_flights", []):
            whole.setdefault((b["width"], b["height"]), []).append(b)
        for (width, height, place), runs in groups.items():
            b = runs[0]
            cold = ("page cache dropped first" if all(r.get("page_cache_dropped") for r in runs)
                    else "page cache not dropped")
            if place is None:  # flown before the placing budget
                budget = ""
            elif place == 0:
                budget = "; --place-budget-ms 0: every frame at full detail"
            else:
                budget = ("; lower detail over the placing budget, --place-budget-ms "
                          f"{fmt(place, 0)}")
            renderer = doc.get("renderer", "thread")
            what = (f"Flythrough over a synthetic {n}² database ({fmt(doc['db_bytes'] / 1e9, 2)} "
                    f"GB) paged through --cache-mb {fmt(mb, 0)}, {width}×{height}, "
                    f"{fmt(doc['seconds'], 0)} s wall clock, a third turning 60°/s, then 300 m/s "
                    f"low ({cold}{budget}; renderer {renderer}"
                    + (f", {len(runs)} runs" if len(runs) > 1 else "") + ")")
            per = lambda f: "/".join(str(f(r)) for r in runs)
            rss = max(r["paging"]["peak_rss_mb"] for r in runs)
            missed = [r["missed_deadlines"] for r in runs]
            base = whole.get((width, height), []) if place != 0 else []
            baseline = ""
            if base:
                baseline = (f"; the same flight over a 4096² map in memory, in turn: "
                            f"{'/'.join(str(r['missed_deadlines']) for r in base)} missed")
            fullest = [r["paging"]["renderer_fullest_frame"] for r in runs
                       if "renderer_fullest_frame" in r["paging"]]
            held = ""
            if fullest:
                top = max(fullest, key=lambda x: x["rss_mb"])
                held = (f"; the renderer's fullest frame {fmt(top['rss_mb'], 0)} MB: tile cache "
                        f"{fmt(top['tile_cache_mb'], 0)}, map pages "
                        f"{fmt(top['map_pages_held_mb'], 0)}, the rest "
                        f"{fmt(top['rest_mb'], 0)}")
            p.row(what + ": peak resident memory; missed fields", "≤ 2 GB; 0 missed",
                  f"peak RSS {fmt(rss, 0)} MB" + (" (field and renderer processes)"
                                                 if renderer == "process" else "") + held
                  + f"; {'/'.join(str(m) for m in missed)} missed of {b['fields']} fields; "
                  f"renderer {per(lambda r: fmt(r['render_fps'], 1))} fps{baseline}",
                  status(rss <= 2048 and max(missed) == 0), cmd)
            # The target is at 720×486; at other sizes the figure is reported.
            targeted = (width, height) == (720, 486)
            late = [r["paging"]["frames_with_substitutions_after_1s"] for r in runs]
            p.row(what + ": tiles drawn from a coarser level",
                  "none after the first second" if targeted else "—",
                  f"{'/'.join(str(x) for x in late)} frames after the first second "
                  f"({per(lambda r: r['paging']['frames_with_substitutions'])} of "
                  f"{per(lambda r: r['paging']['frames'])} in all; at most "
                  f"{max(r['paging']['max_substituted_per_frame'] for r in runs)} tiles a "
                  f"frame, {per(lambda r: fmt(r['paging']['mean_substituted_per_frame'], 2))} "
                  "mean)",
                  status(max(late) == 0) if targeted else NO_TARGET, cmd)
            p.row(what + ": tiles read; placing the frame's tiles on the renderer's thread", "—",
                  f"{per(lambda r: fmt(r['paging']['tiles_read_per_s'], 0))} tiles/s "
                  f"({per(lambda r: fmt(r['paging']['bytes_read'] / 2**20, 0))} MiB in all); "
                  f"placing {per(lambda r: fmt(r['paging']['page_ms_mean'], 2))} ms mean, "
                  f"{per(lambda r: fmt(r['paging']['page_ms_max'], 1))} ms max a frame",
                  NO_TARGET, cmd)
            if all("renderer_silence_ms_max" in r["paging"] for r in runs):
                restarts = [len(r["renderer_restarts"]) for r in runs]
                causes = [x["cause"] for r in runs for x in r["renderer_restarts"]]
                causes = causes[:3] + ([f"{len(causes) - 3} more"] if len(causes) > 3 else [])
                p.row(what + ": renderer restarts; the renderer's longest silence in a frame "
                      "(between two of its signs of life; each process's first frame apart)",
                      "0 restarts",
                      f"{'/'.join(str(x) for x in restarts)} restarts"
                      + (f" ({'; '.join(causes)})" if causes else "")
                      + f"; longest silence {per(lambda r: fmt(r['paging']['renderer_silence_ms_max'], 0))}"
                      f" ms ({' / '.join(r['paging']['renderer_silence_max_between'] for r in runs)}),"
                      f" p99 {per(lambda r: fmt(r['paging']['renderer_silence_ms_p99'], 0))} ms",
                      status(max(restarts) == 0), cmd)
            if "frames_reduced_detail" in b["paging"]:
                p.row(what + ": frames drawn at lower detail; age of the frame each field is "
                      "warped from", "—",
                      f"{per(lambda r: r['paging']['frames_reduced_detail'])} of "
                      f"{per(lambda r: r['paging']['frames'])} frames (detail mean "
                      f"{per(lambda r: fmt(r['paging']['detail_mean'], 2))}, lowest "
                      f"{fmt(min(r['paging']['detail_min'] for r in runs), 2)}); frame age p50 "
                      f"{per(lambda r: fmt(r['frame_age_ms']['p50'], 0))} ms, p99 "
                      f"{per(lambda r: fmt(r['frame_age_ms']['p99'], 0))} ms, max "
                      f"{per(lambda r: fmt(r['frame_age_ms']['max'], 0))} ms", NO_TARGET, cmd)
    if not docs:
        return
    doc = docs[-1]
    cmd = "`" + doc["command"] + "`"
    pw, ww = doc["paged_4096"], doc["whole_4096"]
    pms = [r["render_ms_mean"] for r in pw]
    wms = [r["render_ms_mean"] for r in ww]
    rs = ratios(pms, wms)
    subs = [r["paging"]["frames_with_substitutions"] for r in pw]
    p.row("Frame time paged against in memory: the same 4096² flight (15 s) through "
          "--cache-mb 64 and loaded whole, in turn (mean render time per frame, paging "
          "included; both at full detail, --place-budget-ms 0)", "≤ 1.3×",
          f"{spread(rs, 2, '×')}; {spread(pms, 1, ' ms')} against {spread(wms, 1, ' ms')}; "
          f"{'/'.join(str(x) for x in subs)} frames with substitutions",
          status(statistics.median(rs) <= 1.3), cmd)


def detail(p):
    """render_detail.json (bench-render detail): the lower detail a paged flight draws over its
    placing budget, time and error per step."""
    s = (p.load("render_detail.json") or {}).get("detail")
    if not s:
        return
    p.group = "Terrain database"
    cmd = p.command("render_detail", "detail")
    parts = [f"{fmt(r['detail'], 2)}: level 0 to {fmt(r['level0_reach_km'], 1)} km, "
             f"{fmt(r['mae_pct_vs_reference'], 3)} % "
             f"({fmt(r['mae_pct_vs_detail_1'], 3)} % from detail 1 at "
             f"{s['image'].replace('x', '×')}), {spread(r['ms_runs'], 1, ' ms')}"
             for r in s["rows"]]
    p.row("Lower detail (what a paged flight draws over its placing budget; levels auto, one "
          f"ray per pixel, synthetic {s['map'].split()[-1]}², pitch {fmt(s['pitch_deg'], 0)}°): "
          f"by detail, how far level 0 reaches, the colour error at "
          f"{s['error_image'].replace('x', '×')} against a 4×4 supersampled reference, the "
          f"difference from the full-detail frame, frame time at "
          f"{s['image'].replace('x', '×')} (one thread)", "—", "; ".join(parts), NO_TARGET, cmd)


def insets(p):
    """render_insets_*.json (bench-render insets): a synthetic map with a high-resolution
    inset, the frame's cost and error against the whole fine terrain rendered in memory and the
    global map alone, at 720×486 and 1920×1080."""
    p.group = "Terrain database"
    for image in ("720x486", "1920x1080"):
        doc = (p.load(f"render_insets_{image}.json") or {}).get("insets")
        if not doc:
            continue
        cmd = p.command(f"render_insets_{image}", "insets")
        rows = doc["rows"]
        size = doc["map"].split()[-1]
        what = (f"Insets: a synthetic {size}² map at {fmt(doc['spacing_m'], 0)} m with a "
                f"{doc['inset']['cells']}-cell inset {doc['inset']['factor']} times finer "
                f"({fmt(doc['inset']['spacing_m'], 0)} m), three views of it, "
                f"{image.replace('x', '×')}, 1 thread")
        p.row(what + ": image where the inset shows against the whole fine terrain rendered in "
              "memory (mean colour error); the global map alone there", "matches (≤ 0.05 %)",
              "; ".join(f"{r['view']}: {fmt(r['mae_pct_inset_vs_whole'], 4)} % over "
                        f"{fmt(100 * r['inset_pixel_share'], 0)} % of the frame (global alone "
                        f"{fmt(r['mae_pct_global_inset_vs_whole'], 2)} %)" for r in rows),
              status(max(r["mae_pct_inset_vs_whole"] for r in rows) <= 0.05), cmd)
        p.row(what + ": frame time with the inset against the global map alone and the whole "
              "fine terrain in memory", "—",
              "; ".join(f"{r['view']}: {spread(r['nested']['ms_runs'], 1, ' ms')}, "
                        f"{spread(ratios(r['nested']['ms_runs'], r['global']['ms_runs']), 2, '×')}"
                        f" the global map's, "
                        f"{spread(ratios(r['nested']['ms_runs'], r['whole']['ms_runs']), 2, '×')}"
                        f" the whole fine map's" for r in rows),
              NO_TARGET, cmd)


# --- claims --------------------------------------------------------------------------------------

def casters(p):
    p.group = "Ray casters"
    doc = p.load("caster_bench.json")
    if not doc:
        return
    cmd = p.command("caster_bench")
    for size in ("1920/1080", "720/486"):
        naive = gbench_find(doc, f"BM_Caster/naive/{size}")
        fast = gbench_find(doc, f"BM_Caster/fast/{size}")
        if not (naive and fast):
            continue
        n = gbench_runs(doc, naive, "s_per_pixel")
        f = gbench_runs(doc, fast, "s_per_pixel")
        w, h = size.split("/")
        p.row(f"Fast caster (single level) vs naive: Puget Sound flight view, {w}×{h}, 1 thread",
              "≥ 10×",
              f"{spread(ratios(n, f), 1, '×')}; {spread(f, 1, ' ns/px', 1e9)} vs "
              f"{fmt(statistics.median(n) * 1e9, 0)} ns/px",
              status(statistics.median(ratios(n, f)) >= 10), cmd)
        if size == "1920/1080":
            mae = gbench_runs(doc, fast, "mae_pct_vs_reference")
            p.row(f"Fast caster error against the reference caster, same view, {w}×{h}",
                  "—", f"{fmt(max(mae), 3)} % mean absolute colour error", NO_TARGET, cmd)
    naive = gbench_find(doc, "BM_CasterSweep/naive")
    fast = gbench_find(doc, "BM_CasterSweep/fast")
    if naive and fast:
        n = gbench_runs(doc, naive, "s_per_pixel")
        f = gbench_runs(doc, fast, "s_per_pixel")
        p.row("Fast vs naive over the 50-pose sweep (5 m to 20 km up, pitch +10° to −85°), 720×486",
              "—", f"{spread(ratios(n, f), 1, '×')}; {spread(f, 1, ' ns/px', 1e9)}", NO_TARGET, cmd)


def renderer(p):
    p.group = "Renderer at full speed"
    doc = p.load("render_bench.json")
    if not doc:
        return
    s = doc.get("speed")
    if s:
        cmd = p.command("render_bench", "speed")
        rows = {r["name"]: r for r in s["rows"]}
        naive, single, auto, auto4 = (rows[k] for k in
                                      ("naive", "levels 0", "levels auto", "levels auto, 4 lanes"))
        where = f"synthetic {s['map'].split()[-1]}², {s['image'].replace('x', '×')}, 1 thread"
        r = ratios(naive["ms_runs"], auto["ms_runs"])
        p.row(f"Multiresolution caster (levels auto) vs naive, {where}", "≥ 50×",
              f"{spread(r, 1, '×')}; {fmt(auto['ns_per_pixel'], 1)} vs "
              f"{fmt(naive['ns_per_pixel'], 0)} ns/px (best frames)",
              status(statistics.median(r) >= 50), cmd)
        r = ratios(naive["ms_runs"], auto4["ms_runs"])
        p.row(f"The same with four lanes (a processor without AVX-512), {where}", "≥ 50×",
              f"{spread(r, 1, '×')}", status(statistics.median(r) >= 50), cmd)
        r = ratios(single["ms_runs"], auto["ms_runs"])
        p.row(f"Multiresolution vs single level (levels 0), {where}", "≥ 3×",
              f"{spread(r, 2, '×')}, frames taken in turn; four lanes "
              f"{spread(ratios(single['ms_runs'], auto4['ms_runs']), 2, '×')}",
              status(statistics.median(r) >= 3), cmd)
        r = ratios(naive["ms_runs"], single["ms_runs"])
        p.row(f"Single level vs naive, {where}", "—",
              f"{spread(r, 1, '×')}; colour difference {fmt(s['mae_pct_levels0_vs_naive'], 3)} %",
              NO_TARGET, cmd)
        ns = [ms * 1e6 / (int(s["image"].split("x")[0]) * int(s["image"].split("x")[1]))
              for ms in auto["ms_runs"]]
        p.row(f"Multiresolution caster, time per pixel per thread, {where}", "≤ 4 ns/px (stretch)",
              spread(ns, 1, " ns/px"), status(statistics.median(ns) <= 4), cmd)
    s = doc.get("packets")
    if s:
        rows = {r["name"]: r for r in s["rows"]}
        r0 = ratios(rows["levels 0, one column at a time"]["ms_runs"], rows["levels 0"]["ms_runs"])
        ra = ratios(rows["levels auto, rows one by one"]["ms_runs"], rows["levels auto"]["ms_runs"])
        p.row(f"Vector lanes: levels 0 four columns at a time vs one, levels auto rows in batches "
              f"vs one by one, synthetic {s['map'].split()[-1]}², {s['image'].replace('x', '×')}, "
              "1 thread", "—", f"levels 0 {spread(r0, 2, '×')}; levels auto {spread(ra, 2, '×')}; "
              "frames taken in turn", NO_TARGET, p.command("render_bench", "packets"))
    s = doc.get("sensitivity")
    if s:
        cmd = p.command("render_bench", "sensitivity")
        by = {(r["map_size"], r["levels"]): r for r in s["rows"]}
        sizes = sorted({r["map_size"] for r in s["rows"]})
        small, big = sizes[0], sizes[-1]
        for levels in ("0", "auto"):
            r = ratios(by[(big, levels)]["ms_runs"], by[(small, levels)]["ms_runs"])
            p.row(f"Output sensitivity: frame time over the {big}² map / its {small}² crop, "
                  f"levels {levels}, {s['image'].replace('x', '×')}", "≤ 1.3×",
                  spread(r, 2, "×"), status(statistics.median(r) <= 1.3), cmd)
    s = doc.get("threads")
    if s:
        cmd = p.command("render_bench", "threads")
        rows = s["rows"]
        one = [r for r in rows if r["name"].startswith("1 thread")]
        two = [r for r in rows if r["name"] == "2 threads"][0]
        fastest = min(one, key=lambda r: r["ms"])
        r = ratios(fastest["ms_runs"], two["ms_runs"])
        value = f"{spread(r, 2, '×')} the faster core alone"
        if len(one) == 2:
            together = 1.0 / (1.0 / one[0]["ms"] + 1.0 / one[1]["ms"])
            value += (f"; {fmt(100 * together / two['ms'], 0)} % of the two cores' capacity "
                      f"(one thread {fmt(one[0]['ms'], 1)} / {fmt(one[1]['ms'], 1)} ms on each "
                      f"core, best frames)")
        load = p.loads.get("render_bench")
        if load is not None:
            value += f"; load average {fmt(load, 1)} when the benchmark started"
        p.row(f"Two threads vs one, levels auto, synthetic {s['map'].split()[-1]}², "
              f"{s['image'].replace('x', '×')}", "≥ 1.85×", value,
              status(statistics.median(r) >= 1.85), cmd)
    for key, label in (("headings", "turned to the eight compass headings"),
                       ("pitches", "tilted down from −5° to −60°")):
        s = doc.get(key)
        if not s:
            continue
        cmd = p.command("render_bench", key)
        r = [row["levels0"]["ms"] / row["auto"]["ms"] for row in s["rows"]]
        mae = [row["mae_pct_auto_vs_levels0"] for row in s["rows"]]
        p.row(f"Multiresolution vs single level, the camera {label} "
              f"(best of {s['repeat']} each, in turn)", "—",
              f"{fmt(min(r), 2)}–{fmt(max(r), 2)}× over {len(r)} views; colour difference "
              f"{fmt(min(mae), 3)}–{fmt(max(mae), 3)} %", NO_TARGET, cmd)
    s = doc.get("quality")
    if s:
        cmd = p.command("render_bench", "quality")
        by = {(r["levels"], r["supersample"]): r for r in s["rows"]}
        a, z = by[("auto", 1)], by[("0", 1)]
        p.row(f"Colour error against a 4×4 supersampled reference, one ray per pixel "
              f"({s['error_image'].replace('x', '×')}, synthetic {s['map'].split()[-1]}², "
              f"pitch {fmt(s['pitch_deg'], 0)}°)", "—",
              f"levels auto {fmt(a['mae_pct_vs_reference'], 3)} %, levels 0 "
              f"{fmt(z['mae_pct_vs_reference'], 3)} %", NO_TARGET, cmd)
        plot = ""
        if os.path.exists(os.path.join(os.path.dirname(p.data_dir), "speed_error.png")):
            plot = ("\n\n![speed against error](results/speed_error.png)\n\n(plot: "
                    "`scripts/plot-speed-error.sh docs/results/data/render_bench.json "
                    "docs/results/speed_error.png`)")
        lines = [f"| caster | rays per pixel | frame ms, {s['image'].replace('x', '×')} | ns/px | "
                 "MAE % vs 4×4 reference |",
                 "| --- | ---: | ---: | ---: | ---: |"]
        for levels in ("0", "auto"):
            for ss in (1, 2, 4):
                r = by.get((levels, ss))
                if r:
                    lines.append(f"| levels {levels} | {ss} | {spread(r['ms_runs'], 1)} | "
                                 f"{fmt(r['ns_per_pixel'], 1)} | "
                                 f"{fmt(r['mae_pct_vs_reference'], 3)} |")
        p.section(*(
            "Speed against error: rays per pixel (`--supersample`)",
            f"Time at {s['image'].replace('x', '×')} (one thread, frame times in ms: median, range, runs), error at "
            f"{s['error_image'].replace('x', '×')} against a 4×4 supersampled reference "
            f"(synthetic {s['map'].split()[-1]}², pitch {fmt(s['pitch_deg'], 0)}°). "
            "`--supersample N` is a manual setting of `ig-render` and the benchmark: N rays per "
            "pixel stacked vertically, averaged. Command: " + cmd + ".",
            "\n".join(lines) + plot))
    s = doc.get("stream")
    if s:
        p.row(f"Consecutive frames overlapped (`FrameStream`) vs one at a time, {s['threads']} "
              f"threads, {s['frames']} frames of a flight, synthetic {s['map'].split()[-1]}², "
              f"{s['image'].replace('x', '×')}", "—",
              f"{fmt(s['ms_per_frame_one_at_a_time'] / s['ms_per_frame_overlapped'], 2)}× "
              f"({fmt(s['ms_per_frame_one_at_a_time'], 1)} vs "
              f"{fmt(s['ms_per_frame_overlapped'], 1)} ms a frame, 1 run); images "
              f"{'identical' if s['identical'] else 'DIFFER'}", NO_TARGET,
              p.command("render_bench", "stream"))
    s = doc.get("flight")
    if s:
        cmd = p.command("render_bench", "flight")
        ratios_ = []
        for key in ("mae_pct_frame_to_frame_levels0", "mae_pct_frame_to_frame_auto"):
            v = s[key]
            ratios_.append((max(v) / statistics.median(v), statistics.median(v)))
        p.row(f"Temporal stability along a slow straight flight ({s['frames']} frames of 5 m, "
              f"{s['image'].replace('x', '×')}): worst / median frame-to-frame difference", "—",
              f"levels auto {fmt(ratios_[1][0], 2)} (median {fmt(ratios_[1][1], 3)} %), "
              f"levels 0 {fmt(ratios_[0][0], 2)} (median {fmt(ratios_[0][1], 3)} %)",
              NO_TARGET, cmd)


def span(p):
    """The span caster against the Comanche-style peer and the multiresolution caster, per view
    (bench-render span)."""
    p.group = "Span caster"
    doc = p.load("span_bench.json")
    if not doc or "span" not in doc:
        return
    s = doc["span"]
    cmd = p.command("span_bench", "span")
    rows = s["rows"]
    image = s["image"].replace("x", "×")
    err_image = s["error_image"].replace("x", "×")
    issue = rows[0]
    view = issue["view"].replace("^2", "²")
    r = ratios(issue["span"]["ms_runs"], issue["comanche"]["ms_runs"])
    px = issue["span"]["ns_per_pixel"] / issue["span"]["ms"]  # ns per pixel per ms
    p.row(f"Span caster vs a Comanche-style span renderer, {view}, {image}, 1 thread "
          f"(frames in turn, best of {s['repeat']})", "≤ 1× (≤ 4 ns/px)",
          f"{spread(r, 2, '×')}; {spread(issue['span']['ms_runs'], 1, ' ns/px', px)} vs "
          f"{spread(issue['comanche']['ms_runs'], 1, ' ns/px', px)}; samples/px "
          f"{fmt(issue['span']['steps_per_pixel'], 2)} vs "
          f"{fmt(issue['comanche']['samples_per_pixel'], 2)}",
          status(statistics.median(r) <= 1.0 and issue["span"]["ns_per_pixel"] <= 4.0), cmd)
    rm = ratios(issue["span"]["ms_runs"], issue["multires"]["ms_runs"])
    p.row(f"Span caster vs the multiresolution fast caster (levels auto), {view}, {image}, "
          "1 thread (frames in turn)", "—",
          f"{spread(rm, 2, '×')}; {spread(issue['multires']['ms_runs'], 1, ' ns/px', px)}",
          NO_TARGET, cmd)
    spans = [row for row in rows if row["path"] == "span"]
    worse = [row["view"].replace("^2", "²") for row in spans
             if row["mae_pct_span"] > row["mae_pct_multires"] * 1.1 + 0.02]
    p.row(f"Span caster colour error against a 4×4 supersampled reference ({err_image}), "
          f"{len(spans)} views drawn on the span path", "≤ multiresolution caster's",
          f"{fmt(min(r_['mae_pct_span'] for r_ in spans), 3)}–"
          f"{fmt(max(r_['mae_pct_span'] for r_ in spans), 3)} % vs "
          f"{fmt(min(r_['mae_pct_multires'] for r_ in spans), 3)}–"
          f"{fmt(max(r_['mae_pct_multires'] for r_ in spans), 3)} %; peer "
          f"{fmt(min(r_['mae_pct_comanche'] for r_ in spans), 3)}–"
          f"{fmt(max(r_['mae_pct_comanche'] for r_ in spans), 3)} %"
          + (f"; worse than 1.1× the multiresolution caster's + 0.02 on: {', '.join(worse)}"
             if worse else ""),
          status(not worse), cmd)
    t = doc.get("span_threads")
    if t:
        tr = ratios(t["one"]["ms_runs"], t["two"]["ms_runs"])
        p.row(f"Span caster, two threads vs one, {view}, {image} (frames in turn, "
              f"{t['repeat']} each)", "—",
              f"{spread(tr, 2, '×')}; images {'identical' if t['identical'] else 'DIFFER'}",
              NO_TARGET, p.command("span_bench", "span-threads"))
    cg = p.load("span_callgrind.json")
    if cg and cg.get("runs"):
        main = cg["runs"][0]["view"]  # the view of the before/after pair
        runs = {(r["caster"], r["revision"]): r for r in cg["runs"] if r["view"] == main}

        def per_px(r, key="instructions"):
            return fmt(r[key] / r["pixels"], 0)

        parts = []
        before, after = runs.get(("span", "before")), runs.get(("span", "after"))
        if before and after:
            parts.append(f"span {per_px(before)} → {per_px(after)} (columns "
                         f"{per_px(before, 'columns')} → {per_px(after, 'columns')}, resample "
                         f"{per_px(before, 'resample')} → {per_px(after, 'resample')})")
        fast = runs.get(("fast", "after"))
        if fast and after:
            parts.append(f"multiresolution fast caster {per_px(fast)} "
                         f"(span / fast {fmt(after['instructions'] / fast['instructions'], 2)})")
        for r in cg["runs"]:
            if r["revision"] == "after" and r["caster"] == "span" and r["view"] != main:
                parts.append(f"{r['view']}: span {per_px(r)} (resample {per_px(r, 'resample')})")
        p.row(f"Span caster instructions per pixel (callgrind), {main}, "
              f"{cg['camera'].replace('x', '×')}, {cg['map']}", "—", "; ".join(parts), NO_TARGET,
              f"`{cg['command']}`")
    lines = ["| view | path | span ns/px | samples/px | peer ns/px | peer samples/px | span / peer | "
             "multires ns/px | MAE span % | MAE multires % | MAE peer % |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for row in rows:
        a, m, c = row["span"], row["multires"], row["comanche"]
        lines.append(f"| {row['view'].replace('^2', '²')} | {row['path']} | "
                     f"{fmt(a['ns_per_pixel'], 1)} | {fmt(a['steps_per_pixel'], 2)} | "
                     f"{fmt(c['ns_per_pixel'], 1)} | {fmt(c['samples_per_pixel'], 2)} | "
                     f"{fmt(row['span_over_comanche'], 2)} | {fmt(m['ns_per_pixel'], 1)} | "
                     f"{fmt(row['mae_pct_span'], 3)} | {fmt(row['mae_pct_multires'], 3)} | "
                     f"{fmt(row['mae_pct_comanche'], 3)} |")
    load = p.loads.get("span_bench")
    p.section(*(
        "Span caster per view",
        f"Best of {s['repeat']} frames at {image} on one thread, the three renderers' frames "
        f"taken in turn; colour error at {err_image} against a 4×4 supersampled reference. "
        "\"path\": which renderer drew the span caster's frame (steep views go to the fast "
        "caster). The peer is a Comanche-style renderer written for the benchmark "
        "(`docs/design/span_renderer.md`). Command: " + cmd + "."
        + (f" Load average {fmt(load, 1)} when it started." if load is not None else ""),
        "\n".join(lines)))

def appearance(p):
    p.group = "Appearance and batch rendering"
    doc = p.load("render_autosample.json")
    s = (doc or {}).get("autosample")
    if s:
        cmd = p.command("render_autosample", "autosample")
        sweep = {r["variant"]: r for r in s["sweep"]}
        one, auto, four = sweep["1 ray"], sweep["auto"], sweep["4 rays"]
        p.row(f"`--supersample auto` over a pitch sweep (0° to −70°, synthetic "
              f"{s['map'].split()[-1]}², {s['image'].replace('x', '×')}, 1 thread): sweep time "
              f"and mean colour error against a 4×4 supersampled reference", "—",
              f"auto {fmt(auto['sweep_ms'], 0)} ms, {fmt(auto['mean_mae_pct_vs_reference'], 3)} %; "
              f"1 ray {fmt(one['sweep_ms'], 0)} ms, {fmt(one['mean_mae_pct_vs_reference'], 3)} %; "
              f"4 rays {fmt(four['sweep_ms'], 0)} ms, "
              f"{fmt(four['mean_mae_pct_vs_reference'], 3)} % (best of {s['repeat']} per view)",
              NO_TARGET, cmd)
        sh = s["shimmer"]
        p.row(f"Shimmer along a slow flight ({sh['frames']} frames of 5 m, pitch "
              f"{fmt(sh['pitch_deg'], 0)}°, {sh['image'].replace('x', '×')}): mean "
              f"frame-to-frame difference", "—",
              f"1 ray {fmt(sh['frame_to_frame_mae_pct_1'], 3)} %, auto "
              f"{fmt(sh['frame_to_frame_mae_pct_auto'], 3)} %, 4 rays "
              f"{fmt(sh['frame_to_frame_mae_pct_4'], 3)} %, 16-ray render "
              f"{fmt(sh['frame_to_frame_mae_pct_16'], 3)} %", NO_TARGET, cmd)
        lines = ["| pitch | variant | rays per pixel | frame ms | MAE % vs 4×4 reference |",
                 "| ---: | --- | ---: | ---: | ---: |"]
        for r in s["rows"]:
            lines.append(f"| {fmt(r['pitch_deg'], 0)}° | {r['name']} | "
                         f"{fmt(r['rays_per_pixel'], 0)} | {spread(r['ms_runs'], 1)} | "
                         f"{fmt(r['mae_pct_vs_reference'], 3)} |")
        p.section("Supersampling driven by pitch (`--supersample auto`)",
                  f"Time at {s['image'].replace('x', '×')} (one thread; frame times in ms: "
                  f"median, range, runs), error at {s['error_image'].replace('x', '×')} against "
                  f"a 4×4 supersampled reference, synthetic {s['map'].split()[-1]}². Command: "
                  + cmd + ".", "\n".join(lines))
    lit = (p.load("render_lighting.json") or {}).get("lighting")
    if lit:
        cmd = p.command("render_lighting", "lighting")
        for image in ("720x486", "1920x1080"):
            parts = [f"{c['map']} {spread(c['pass_ns_per_pixel_runs'], 1)} ns/px, "
                     f"{spread(c['pass_over_frame_runs'], 2, '×')} the frame's"
                     for c in lit["cost"] if c["image"] == image]
            p.row(f"Sun lighting at render time: CPU time of the pass over a finished "
                  f"{image.replace('x', '×')} frame (one thread), and against the frame's own "
                  f"(multiresolution fast caster, unlit)", "—", "; ".join(parts), NO_TARGET, cmd)
        e = lit["error"]

        def rng(key, sub):
            v = [r[key][sub] for r in e]
            return f"{fmt(min(v), 3)}–{fmt(max(v), 3)} %"
        p.row(f"Sun lighting at render time against the baked relight (map colours lit, pyramid "
              f"averaging lit colours), same caster, {lit['error_image'].replace('x', '×')}, "
              f"pitches −4°/−10°/−30°, synthetic and Puget Sound, haze on: mean colour error",
              "—", f"single level {rng('levels0', 'deferred_vs_baked_mae_pct')}, "
              f"multiresolution {rng('multires', 'deferred_vs_baked_mae_pct')} (level-0 normals "
              f"at every distance: {rng('multires', 'level0_normals_vs_baked_mae_pct')})",
              NO_TARGET, cmd)
        p.row("… and against a 4×4 supersampled reference render of the baked relight: render-"
              "time lighting vs baked, multiresolution caster", "—",
              f"render time {rng('multires', 'deferred_vs_reference_mae_pct')}, baked "
              f"{rng('multires', 'baked_vs_reference_mae_pct')}; single level: render time "
              f"{rng('levels0', 'deferred_vs_reference_mae_pct')}, baked "
              f"{rng('levels0', 'baked_vs_reference_mae_pct')}", NO_TARGET, cmd)
        lines = ["| map | pitch | caster | vs baked: MAE % (PSNR dB) | level-0 normals vs baked "
                 "| vs 4×4 ref: render time | level-0 normals | baked |",
                 "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: |"]
        for r in e:
            for key, name in (("levels0", "single level"), ("multires", "multiresolution")):
                x = r[key]
                lines.append(f"| {r['map']} | {fmt(r['pitch_deg'], 0)}° | {name} | "
                             f"{fmt(x['deferred_vs_baked_mae_pct'], 3)} "
                             f"({fmt(x['deferred_vs_baked_psnr_db'], 1)}) | "
                             f"{fmt(x['level0_normals_vs_baked_mae_pct'], 3)} | "
                             f"{fmt(x['deferred_vs_reference_mae_pct'], 3)} | "
                             f"{fmt(x['level0_normals_vs_reference_mae_pct'], 3)} | "
                             f"{fmt(x['baked_vs_reference_mae_pct'], 3)} |")
        p.section("Sun lighting at render time against the baked relight",
                  f"Errors at {lit['error_image'].replace('x', '×')} (mean absolute colour error, "
                  f"% of full scale), sun at azimuth {fmt(lit['sun_deg'][0], 0)}°, elevation "
                  f"{fmt(lit['sun_deg'][1], 0)}°, haze a quarter of the map's extent. Command: "
                  + cmd + ".", "\n".join(lines))
    fill = (p.load("render_edge_fill.json") or {}).get("edge-fill")
    if fill:
        cmd = p.command("render_edge_fill", "edge-fill")
        rows = fill["rows"]

        def span_of(key):
            v = [r[key] for r in rows]
            return f"{fmt(min(v), 2)}–{fmt(max(v), 2)} %"
        p.row(f"PRP beyond the rendered frame ({fill['map']}, {fill['image'].replace('x', '×')}, "
              f"margin {fill['margin']}, the view turned by 1 to 2 margins, level and rolled 15°): "
              f"mean colour error over the pixels taken from beyond the frame against a true "
              f"render", "—",
              f"sky (default) {span_of('sky_beyond_mae_pct')}, edge repeated "
              f"{span_of('repeat_beyond_mae_pct')}, sky-haze {span_of('sky-haze_beyond_mae_pct')}",
              NO_TARGET, cmd)
        lines = ["| pitch | roll | turn px | beyond the frame % | repeat | sky | sky-haze |",
                 "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for r in rows:
            lines.append(f"| {fmt(r['pitch_deg'], 0)}° | {fmt(r['roll_deg'], 0)}° | "
                         f"{fmt(r['turn_px'], 0)} | {fmt(r['outside_pct'], 2)} | "
                         f"{fmt(r['repeat_beyond_mae_pct'], 2)} ({fmt(r['repeat_mae_pct'], 3)}) | "
                         f"{fmt(r['sky_beyond_mae_pct'], 2)} ({fmt(r['sky_mae_pct'], 3)}) | "
                         f"{fmt(r['sky-haze_beyond_mae_pct'], 2)} "
                         f"({fmt(r['sky-haze_mae_pct'], 3)}) |")
        p.section("The PRP's fill beyond the rendered frame (`--edge-fill`)",
                  "Mean absolute colour error (% of full scale) over the output pixels taken from "
                  "beyond the frame, the whole field's in brackets, against a true render at the "
                  "field's pose. Command: " + cmd + ".", "\n".join(lines))
    b = p.load("render_batch.json")
    if b:
        fps_batch = [b["frames"] / t for t in b["batch_s"]]
        fps_single = [b["frames"] / t for t in b["single_s"]]
        p.row(f"Batch rendering, `ig-render --poses` ({b['frames']} poses, "
              f"{b['image'].replace('x', '×')}, {b['map']}, {b['cores']} cores) vs one "
              f"`ig-render` process per frame", "—",
              f"{spread(fps_batch, 1)} frames/s vs {spread(fps_single, 1)} frames/s: "
              f"{spread(ratios(fps_batch, fps_single), 1, '×')}", NO_TARGET,
              p.command("render_batch"))


def callgrind(p):
    """Instructions per pixel before and after a reorganisation of the caster, from
    caster_callgrind.json when it exists: {"machine", "camera", "map", "runs": [{"levels",
    "kernel", "revision": "before"|"after", "instructions", "pixels", "instructions_per_pixel"}]}
    (an optional "command" says how it was measured)."""
    p.group = "Renderer at full speed"
    doc = p.load("caster_callgrind.json")
    if not doc or not doc.get("runs"):
        return
    keys = []
    for r in doc["runs"]:
        key = (str(r.get("levels", "?")), r.get("kernel", ""))
        if key not in keys:
            keys.append(key)
    parts = []
    for levels, kernel in keys:
        runs = {r.get("revision"): r["instructions_per_pixel"] for r in doc["runs"]
                if (str(r.get("levels", "?")), r.get("kernel", "")) == (levels, kernel)}
        name = f"levels {levels}" + (f" ({kernel})" if kernel else "")
        if "before" in runs and "after" in runs:
            change = 100.0 * (runs["after"] / runs["before"] - 1.0)
            parts.append(f"{name}: {fmt(runs['before'], 0)} → {fmt(runs['after'], 0)} "
                         f"({'+' if change >= 0 else ''}{fmt(change, 0)} %)")
        else:
            parts += [f"{name}, {rev}: {fmt(v, 0)}" for rev, v in runs.items()]
    camera, where = doc.get("camera", "1920x1080"), doc.get("map", "synthetic 16384")
    if doc.get("command"):
        command = f"`{doc['command']}`"
    elif "caster_callgrind" in p.commands:
        command = p.command("caster_callgrind")
    else:
        command = ("`valgrind --tool=callgrind --collect-atstart=no "
                   "--toggle-collect='ig::renderFrame*' build/release/bin/bench-render frame "
                   f"--size {where.split()[-1]} --image {camera} --cache /tmp/cache "
                   "--caster fast --levels auto|0 --repeat 1` (instructions of `ig::renderFrame` "
                   "over the image's pixels)")
    p.row(f"Caster instructions per pixel, before/after reorganisation (callgrind), "
          f"{camera.replace('x', '×')}, {where}", "—", "; ".join(parts), NO_TARGET, command)


def warp(p):
    p.group = "Post-rendering processor"
    doc = p.load("warp_bench.json")
    if not doc:
        return
    cmd = p.command("warp_bench")
    auto = gbench_find(doc, "BM_PrpWarpUyvyField")
    avx2 = gbench_find(doc, "BM_PrpWarpUyvyFieldAvx2")
    remap = gbench_find(doc, "BM_OpenCvRemapField")
    t_auto = gbench_runs(doc, auto, "cpu_time") if auto else []
    if remap and t_auto:
        t_remap = gbench_runs(doc, remap, "cpu_time")
        r = ratios(t_remap, t_auto)
        p.row("PRP warp + UYVY of one 720×243 field, 1 thread, kernel picked at run time, "
              "vs OpenCV cv::remap (RGB only)", "≥ 2×",
              f"{spread(r, 2, '×')}; {spread(t_auto, 0, ' µs')} vs "
              f"{fmt(statistics.median(t_remap), 0)} µs", status(statistics.median(r) >= 2), cmd)
        if avx2:
            t2 = gbench_runs(doc, avx2, "cpu_time")
            r = ratios(t_remap, t2)
            p.row("The same with the AVX2 kernel (a processor without AVX-512)", "≥ 2×",
                  f"{spread(r, 2, '×')}; {spread(t2, 0, ' µs')}",
                  status(statistics.median(r) >= 2), cmd)
    elif t_auto:
        p.row("PRP warp + UYVY of one 720×243 field vs OpenCV cv::remap", "≥ 2×",
              f"not measured: bench-warp was built without OpenCV (libopencv-dev); "
              f"warp alone {spread(t_auto, 0, ' µs')}", "not measured", cmd)
    if t_auto:
        share = [t * 1e-6 * 60000 / 1001 * 100 for t in t_auto]
        p.row("Share of one core for the warp at 59.94 fields/s", "—", spread(share, 1, " %"),
              NO_TARGET, cmd)
    # The out-of-frame fill: run at a time against its per-pixel twin, in the same run.
    for fast_name, twin_name, what in (
            ("BM_PrpWarpUyvyFieldOutsideFilled", "BM_PrpWarpUyvyFieldOutsideFilledPerPixel",
             "sky above the horizon, the edge kept below (`--edge-fill sky`, the default), no "
             "AGC"),
            ("BM_PrpWarpUyvyFieldOutsideHazeAgc", "BM_PrpWarpUyvyFieldOutsideHazeAgcPerPixel",
             "sky and haze (`--edge-fill sky-haze`), AGC on (every pixel sampled again for its "
             "luma)")):
        fast, twin = gbench_find(doc, fast_name), gbench_find(doc, twin_name)
        if not (fast and twin):
            continue
        f = [x * 1e9 for x in gbench_runs(doc, fast, "ns_per_px")]
        t = [x * 1e9 for x in gbench_runs(doc, twin, "ns_per_px")]
        p.row(f"Warp + out-of-frame fill of one 720×243 UYVY field wholly beyond the frame, "
              f"{what}, 1 thread: a run of pixels at a time vs the per-pixel twin (the same "
              f"bytes)", "—",
              f"{spread(ratios(t, f), 1, '×')} faster; {spread(f, 1, ' ns/px')} vs "
              f"{spread(t, 1, ' ns/px')}", NO_TARGET, cmd)
    quarter = gbench_find(doc, "BM_PrpWarpUyvyFieldEdgesFilled")
    if quarter:
        q = [x * 1e9 for x in gbench_runs(doc, quarter, "ns_per_px")]
        p.row("The same with a quarter of the field beyond the frame (default fill)", "—",
              spread(q, 1, " ns/px"), NO_TARGET, cmd)


def depth_warp(p):
    p.group = "Post-rendering processor"
    doc = p.load("depth_warp_bench.json")
    if not doc:
        return
    cmd = p.command("depth_warp_bench")
    depth = gbench_find(doc, "BM_PrpDepthUyvyField")
    scalar = gbench_find(doc, "BM_PrpDepthUyvyFieldScalar")
    poly = gbench_find(doc, "BM_PrpPolyUyvyFieldWithFit")
    if not (depth and poly):
        return
    # The counter is an inverted rate: seconds per pixel.
    d = [x * 1e9 for x in gbench_runs(doc, depth, "ns_per_px")]
    q = [x * 1e9 for x in gbench_runs(doc, poly, "ns_per_px")]
    load = p.loads.get("depth_warp_bench")
    p.row("Depth warp of one 720×243 field (float splat of the 816×582 frame with a z-test, "
          "AVX2 projection of the depths scaled once per frame, points moved to their pixel "
          "centres by the quadratic's Jacobian; fit included), UYVY, 1 thread",
          "≤ 10 ns/px", f"{spread(d, 1, ' ns/px')}; the quadratic with its fit "
          f"{spread(q, 2, ' ns/px')} ({spread(ratios(d, q), 1, '×')})",
          status(statistics.median(d) <= 10.0), cmd)
    fresh = gbench_find(doc, "BM_PrpDepthUyvyFieldNewFrames")
    if fresh:
        nf = [x * 1e9 for x in gbench_runs(doc, fresh, "ns_per_px")]
        p.row("The same with a new frame every field (a renderer as fast as the fields: the "
              "frame's scaled depths and anti-twitter filter made for every field, not once for "
              "a frame's fields)", "—", spread(nf, 1, " ns/px"), NO_TARGET, cmd)
    if scalar:
        sc = [x * 1e9 for x in gbench_runs(doc, scalar, "ns_per_px")]
        p.row("The same with the scalar projection (its bit-identical twin)", "—",
              spread(sc, 1, " ns/px"), NO_TARGET, cmd)
    gather = gbench_find(doc, "BM_PrpDepthUyvyFieldGather")
    if gather:
        g = [x * 1e9 for x in gbench_runs(doc, gather, "ns_per_px")]
        unsettled = gbench_runs(doc, gather, "unsettled_pct")
        splat = gbench_runs(doc, gather, "splat_pct")
        p.row("Depth warp by the gather instead (per field pixel two Newton steps from the "
              "quadratic's point with AVX2 gathers; the splat in the 64×8 tiles where they do not "
              "settle; not the default), the same field, interleaved", "—",
              f"{spread(g, 1, ' ns/px')}; against the splat {spread(ratios(g, d), 2, '×')}; "
              f"{fmt(statistics.median(unsettled), 2)} % of the pixels unsettled, "
              f"{fmt(statistics.median(splat), 2)} % splatted",
              NO_TARGET, cmd)
        gs = gbench_find(doc, "BM_PrpDepthUyvyFieldGatherScalar")
        if gs:
            sc = [x * 1e9 for x in gbench_runs(doc, gs, "ns_per_px")]
            p.row("The gather with its scalar twin (bit-identical)", "—", spread(sc, 1, " ns/px"),
                  NO_TARGET, cmd)


def warp_eval(p):
    p.group = "Post-rendering processor"
    doc = p.load("warp_eval.json")
    if not doc:
        return
    cmd = p.command("warp_eval")
    cells = doc["results"]
    by = {(c["model"], c["horizon"]): c for c in cells}
    models = []
    for c in cells:
        if c["model"] not in models:
            models.append(c["model"])
    horizons = sorted({c["horizon"] for c in cells})
    kmax = horizons[-1]
    poly1, polyk = by[("poly", 1)], by[("poly", kmax)]
    frames = poly1.get("base_frames", "?")
    p.row(f"PRP quadratic warp error against a true render, {len(doc['trajectories'])} shipped "
          f"trajectories over Puget Sound, {doc['size'][0]}×{doc['size'][1]}",
          "—", f"k = 1 field: {fmt(poly1['psnr_db'], 1)} dB / {fmt(poly1['mae_pct'], 2)} %; "
          f"k = {kmax}: {fmt(polyk['psnr_db'], 1)} dB / {fmt(polyk['mae_pct'], 2)} % "
          f"(mean of {frames} base frames)", NO_TARGET, cmd)
    if "auto" in models and "depth" in models:
        diffs = [by[("auto", k)]["psnr_db"] - max(by[("poly", k)]["psnr_db"],
                                                  by[("depth", k)]["psnr_db"]) for k in horizons]
        share = sum(by[("auto", k)].get("depth_fields", 0) for k in horizons) / max(
            1, sum(by[("auto", k)]["base_frames"] for k in horizons))
        ns_auto = statistics.mean(by[("auto", k)]["ns_per_pixel"] for k in horizons)
        ns_depth = statistics.mean(by[("depth", k)]["ns_per_pixel"] for k in horizons)
        ns_poly = statistics.mean(by[("poly", k)]["ns_per_pixel"] for k in horizons)
        p.row("Auto warp (per field: the quadratic, or the depth warp where the quadratic misses "
              "its 5×5 check points by more than 0.25 px), all trajectories: PSNR against the "
              "better of the quadratic and the depth warp alone, worst horizon",
              "≥ −0.25 dB", f"{fmt(min(diffs), 2)} dB (best {fmt(max(diffs), 2)} dB); depth "
              f"warp on {fmt(100 * share, 0)} % of the fields; {fmt(ns_auto, 1)} ns/px against "
              f"{fmt(ns_poly, 1)} (quadratic) and {fmt(ns_depth, 1)} (depth)",
              status(min(diffs) >= -0.25), cmd)
        low = [t for t in doc["trajectories"] if t["trajectory"].endswith("low.csv")]
        if low:
            lb = {(c["model"], c["horizon"]): c for c in low[0]["results"]}
            p.row("Low and fast (low.csv, 40 m at 200 m/s): PSNR at k = 1 → k = "
                  f"{kmax} fields", "—",
                  "; ".join(f"{m} {fmt(lb[(m, 1)]['psnr_db'], 1)} → "
                            f"{fmt(lb[(m, kmax)]['psnr_db'], 1)} dB"
                            for m in ("poly", "depth", "auto") if (m, 1) in lb),
                  NO_TARGET, cmd)
    gathered = p.load("warp_eval_gather.json")
    if gathered and "depth" in models:
        gby = {(c["model"], c["horizon"]): c for c in gathered["results"]}
        dd = [gby[("depth", k)]["psnr_db"] - by[("depth", k)]["psnr_db"] for k in horizons
              if ("depth", k) in gby]
        da = [gby[("auto", k)]["psnr_db"] - by[("auto", k)]["psnr_db"] for k in horizons
              if ("auto", k) in gby and ("auto", k) in by]
        ns_g = statistics.mean(gby[("depth", k)]["ns_per_pixel"] for k in horizons)
        ns_s = statistics.mean(by[("depth", k)]["ns_per_pixel"] for k in horizons)
        p.row("The depth warp by the gather (`--depth-warp gather`) against the splat, all "
              "trajectories, every horizon: PSNR difference", "≥ −0.1 dB",
              f"depth {fmt(min(dd), 2)} to {fmt(max(dd), 2)} dB; auto {fmt(min(da), 2)} to "
              f"{fmt(max(da), 2)} dB; depth {fmt(ns_g, 1)} ns/px in this run, the splat "
              f"{fmt(ns_s, 1)} in the run above (320×240; the interleaved figure is the "
              "benchmark's)",
              status(min(dd + da) >= -0.1), p.command("warp_eval_gather"))
    zero = p.load("warp_eval_levels0.json")
    if zero:
        other = {(c["model"], c["horizon"]): c for c in zero["results"]}
        keys = [k for k in by if k in other]
        db = max(abs(by[k]["psnr_db"] - other[k]["psnr_db"]) for k in keys)
        mae = max(abs(by[k]["mae_pct"] - other[k]["mae_pct"]) for k in keys)
        p.row("The same with frames and truths by the exact single level (`--levels 0`): largest "
              "difference from levels auto over every model and horizon", "—",
              f"{fmt(db, 2)} dB, {fmt(mae, 3)} % MAE", NO_TARGET, p.command("warp_eval_levels0"))
    shown = [k for k in (1, 2, 4, 8) if k in horizons]
    head = "| model | " + " | ".join(f"k = {k}: dB / MAE %" for k in shown) + " | ns/px | fallbacks |"
    lines = [head, "| --- |" + " ---: |" * (len(shown) + 2)]
    for m in models:
        ns = statistics.mean(by[(m, k)]["ns_per_pixel"] for k in horizons)
        fb = sum(by[(m, k)]["fallbacks"] for k in horizons)
        lines.append(f"| {m} | " + " | ".join(
            f"{fmt(by[(m, k)]['psnr_db'], 1)} / {fmt(by[(m, k)]['mae_pct'], 2)}" for k in shown)
            + f" | {fmt(ns, 2)} | {fb} |")
    p.section(*(
        "Warp models against the horizon",
        f"Each model warps a frame rendered at t to t + k fields and is compared with a true "
        f"render there ({doc['size'][0]}×{doc['size'][1]}, margin {doc['margin']} px, levels "
        f"{doc['levels']}; cells: PSNR / mean absolute error in % of full scale, mean over the "
        f"trajectories' base frames). Command: {cmd}; plot: "
        "`scripts/plot-warp-eval.sh docs/results/data/warp_eval.csv docs/warp_eval_prp.png`.",
        "\n".join(lines) + "\n\n![warp error against horizon](warp_eval_prp.png)"))


def moving_targets(p):
    """target_eval.json (target-eval): a moving vehicle's centroid in warped fields against truly
    rendered fields, by horizon; static objects for contrast."""
    p.group = "Post-rendering processor"
    doc = p.load("target_eval.json")
    if not doc:
        return
    cmd = p.command("target_eval")
    rows = doc["horizons"]
    models = [m for m in ("poly", "depth") if m in rows[0]]
    if not models:
        return
    m = models[0]
    by = {r["k"]: r for r in rows}
    kmax = max(by)
    t1, tk = by[1][m]["target"], by[kmax][m]["target"]
    st = [by[k][m]["static"]["mean"] for k in by if by[k][m]["static"]["n"]]
    size = f"{doc['width']}×{doc['height']}"
    p.row(f"Moving target through the {m} warp ({size}, {doc['fov_deg']:.0f}°, the tank of "
          f"`{os.path.basename(doc['scene'])}` seen from `{os.path.basename(doc['trajectory'])}`): "
          f"centroid error in the warped field's ids against a true render at the field's "
          f"instant, mean / max over {t1['n']} base frames, k = 1 and k = {kmax}; static objects "
          "at every horizon", "—",
          f"k = 1: {fmt(t1['mean'], 2)} / {fmt(t1['max'], 2)} px; k = {kmax}: "
          f"{fmt(tk['mean'], 2)} / {fmt(tk['max'], 2)} px; static objects "
          f"{fmt(min(st), 2)}–{fmt(max(st), 2)} px (means)", NO_TARGET, cmd)
    if "target_restamped" in by[kmax][m]:
        r1, rk = by[1][m]["target_restamped"], by[kmax][m]["target_restamped"]
        p.row(f"The same fields with the moving objects re-stamped at the field's instant "
              f"(prp/object_restamp.hpp, {m} warp): the target's centroid error, mean / max, "
              f"k = 1 and k = {kmax}", "within 0.1 px of the static objects' error (the pixel grid)", f"k = 1: "
              f"{fmt(r1['mean'], 2)} / {fmt(r1['max'], 2)} px; k = {kmax}: {fmt(rk['mean'], 2)} / "
              f"{fmt(rk['max'], 2)} px (static {fmt(max(st), 2)})",
              status(max(by[k][m]["target_restamped"]["mean"] for k in by) <= max(st) + 0.1),
              cmd)
    at = p.load("target_eval_720.json")
    if at and "poly" in at["horizons"][0]:
        hs = sorted(at["horizons"], key=lambda r: r["k"])
        p.row(f"The same at {at['width']}×{at['height']} ({at['fov_deg']:.0f}°, the pipeline's "
              f"horizons: frames every 3-4 fields on the target machine), poly warp: the target's "
              f"centroid error by horizon, mean (max) over {hs[0]['poly']['target']['n']} base "
              "frames; static objects", "—",
              "; ".join(f"k = {r['k']}: {fmt(r['poly']['target']['mean'], 2)} "
                        f"({fmt(r['poly']['target']['max'], 2)}) px" for r in hs) +
              f"; static objects {fmt(min(r['poly']['static']['mean'] for r in hs), 2)}–"
              f"{fmt(max(r['poly']['static']['mean'] for r in hs), 2)} px (means)",
              NO_TARGET, p.command("target_eval_720"))
        if "target_restamped" in hs[0]["poly"]:
            p.row(f"The same at {at['width']}×{at['height']} with the moving objects re-stamped "
                  "at the field's instant: the target's centroid error by horizon, mean (max)",
                  "—", "; ".join(f"k = {r['k']}: {fmt(r['poly']['target_restamped']['mean'], 2)} "
                                f"({fmt(r['poly']['target_restamped']['max'], 2)}) px" for r in hs),
                  NO_TARGET, p.command("target_eval_720"))
    tm = doc.get("truth_ms")
    if tm and tm.get("n"):
        p.row(f"Per-field ground truth (`flythrough --truth`, off the field thread) of a {size} "
              f"field over a scene of {doc['objects_in_scene']} objects: visible pixels, boxes, "
              "centroids from the warped ids; exact boxes, ranges and unoccluded pixels (rays "
              "against each model in view), processor time of one thread, mean / p95",
              "≤ 16.7 ms (one field)", f"{fmt(tm['mean'], 2)} / {fmt(tm['p95'], 2)} ms over "
              f"{tm['n']} fields", status(tm["p95"] <= 1001 / 60), cmd)
    head = "| k | " + " | ".join(f"{x} target: mean / p95 / max px | {x} static: mean / p95"
                                 for x in models) + " |"
    lines = [head, "| ---: |" + " ---: | ---: |" * len(models)]
    for k in sorted(by):
        r = by[k]
        cells = []
        for x in models:
            t, s_ = r[x]["target"], r[x]["static"]
            cells.append(f"{fmt(t['mean'], 2)} / {fmt(t['p95'], 2)} / {fmt(t['max'], 2)}"
                         if t["n"] else "—")
            cells.append(f"{fmt(s_['mean'], 2)} / {fmt(s_['p95'], 2)}" if s_["n"] else "—")
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    p.section(
        "Moving targets through the warp",
        f"For {doc['frames']} base frames along `{doc['trajectory']}`, a frame rendered at t (the "
        "naive caster, objects stamped at t) is warped to t + k fields and compared with a true "
        "render there (objects stamped at the field's instant, the field's pose): the centroid of "
        f"object {doc['target']} (the moving tank) and of every static object showing at least "
        f"{doc['min_px']} pixels in both, in output pixels. The warp follows the terrain's motion, "
        "not the vehicle's: the vehicle's error grows with the horizon while the static objects' "
        f"stays at the pixel grid's. Command: {cmd}.",
        "\n".join(lines))


STEREO = (("stereo_puget_720x486", "Puget Sound", "720×486"),
          ("stereo_puget_1920x1080", "Puget Sound", "1920×1080"),
          ("stereo_goleta_720x486", "Goleta", "720×486"),
          ("stereo_goleta_1920x1080", "Goleta", "1920×1080"),
          ("stereo_goleta_500x400", "Goleta", "500×400 (the papers' setting)"))
STEREO_WIDE = (("stereo_puget_720x486_agl0.1", "Puget Sound", "720×486, 5× separation"),
               ("stereo_goleta_720x486_agl0.1", "Goleta", "720×486, 5× separation"))


def stereo(p):
    p.group = "Stereo"
    found, wide = [], []
    for group, names in ((found, STEREO), (wide, STEREO_WIDE)):
        for name, terrain, size in names:
            doc = p.load(name + ".json")
            if doc:
                group.append((name, terrain, size, doc))
    if not found:
        return
    lines = ["| terrain, size | left eye ms | A-buffer right/left | MAE % | integer right/left | "
             "MAE % | Adelson–Hodges right/left | MAE % | command |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    ratios_, maes = [], []
    for name, terrain, size, doc in found + wide:
        res = {r["config"]: r for r in doc["results"]}
        a = res["abuffer"]
        if (name, terrain, size, doc) in found:
            ratios_.append((a["right_over_left"], f"{terrain} {size}"))
            maes.append(a["mae_pct"])
        cells = []
        for c in ("abuffer", "integer", "adelson-hodges"):
            r = res.get(c)
            cells += [fmt(r["right_over_left"], 3), fmt(r["mae_pct"], 3)] if r else ["—", "—"]
        lines.append(f"| {terrain} {size} | {fmt(doc['left_ms_mean'], 1)} | " + " | ".join(cells)
                     + f" | {p.command(name)} |")
    worst = max(ratios_)
    cmds = ", ".join(p.command(n) for n, *_ in found[:1])
    repeat = found[0][3].get("repeat", "?")
    p.row(f"Stereo: right eye by reprojection (A-buffer) / left eye, CPU time, 12-pose sweep, "
          f"{len(found)} terrains and sizes", "≤ 0.15",
          f"{fmt(min(r for r, _ in ratios_), 3)}–{fmt(worst[0], 3)} (highest: {worst[1]}; "
          f"best of {repeat} per pose)", status(worst[0] <= 0.15), cmds + " and the table below")
    p.row("Stereo: right eye colour error against its full ray cast, same runs", "≤ 2 %",
          f"{fmt(min(maes), 3)}–{fmt(max(maes), 3)} % mean absolute error",
          status(max(maes) <= 2), "the table below")
    p.section(*(
        "Per terrain, size and configuration",
        "For each pose of the 12-pose sweep the left eye is cast by the fast caster and the right "
        "eye both reprojected from it (each configuration) and cast in full (the reference); "
        "times are one thread's CPU time, the least of the repeats; right/left is the sum of "
        "right-eye times over the sum of left-eye times. Eye separation 0.02 × height above "
        "the terrain (`--stereo-agl 0.1`: five times as much, so a wider strip at the right edge "
        "is seen only by the right eye and cast). Goleta is `--height data/goleta-512/sba_elev32_wgs84_512x512.tif --color "
        "data/goleta-512/sba_rgb_wgs84_512x512.tif`.",
        "\n".join(lines)))


def pipeline(p):
    p.group = "Real-time pipeline and output"
    auto = [p.load(f"flythrough_auto_{i}.json") for i in range(1, 10)]
    auto = [d for d in auto if d]
    single = [p.load(f"flythrough_levels0_{i}.json") for i in range(1, 10)]
    single = [d for d in single if d]
    if not auto:
        return
    cmd = p.command("flythrough_auto_1")
    missed = [d["missed_deadlines"] for d in auto + single]
    seconds = sum(d["elapsed_s"] for d in auto + single)
    fields = sum(d["fields"] for d in auto + single)
    names = [f"flythrough_auto_{i}" for i in range(1, len(auto) + 1)] + \
        [f"flythrough_levels0_{i}" for i in range(1, len(single) + 1)]
    loads = [p.loads[n] for n in names if n in p.loads]
    load = f"; load average {fmt(min(loads), 1)}–{fmt(max(loads), 1)} as they started" if loads else ""
    p.row("Pipeline on the wall clock, default scenario, 720×486 fields, renderer unthrottled: "
          "missed field deadlines", "0",
          f"{sum(missed)} of {fields} fields in {len(missed)} runs, {fmt(seconds, 0)} s (per run: "
          f"{', '.join(str(m) for m in missed)}{load}); field interval max "
          f"{fmt(max(d['field_interval_ms']['max'] for d in auto + single), 1)} ms",
          status(sum(missed) == 0), cmd)
    value = (f"levels auto {spread([d['render_fps'] for d in auto], 1, ' fps')}")
    if single:
        value += f"; levels 0 {spread([d['render_fps'] for d in single], 1, ' fps')}"
    frame = f"{auto[0].get('render_width_level', '?')}×{auto[0].get('render_height_level', '?')}"
    mode = auto[0].get("renderer", "thread")
    cores = "every core" if mode == "process" else "all cores but one"
    p.row(f"Renderer frame rate in the pipeline (renderer {mode}, {cores}, Puget Sound, {frame} "
          "level frames)", "—", value, NO_TARGET,
          cmd + (" and the same with `--levels 0`" if single else ""))
    p.row("Frame age at output, p50 / p99, levels auto", "—",
          f"p50 {spread([d['frame_age_ms']['p50'] for d in auto], 1, ' ms')}; p99 "
          f"{spread([d['frame_age_ms']['p99'] for d in auto], 1, ' ms')}", NO_TARGET, cmd)
    sim = p.load("flythrough_simulated.json")
    if sim:
        age = sim["frame_age_ms"]
        p.row("Simulated clock (every render modelled as 1/12 s): frame age p50 / p99 / max, "
              "reproducible run to run", "below 1/12 s (83.3 ms)",
              f"{fmt(age['p50'], 1)} / {fmt(age['p99'], 1)} / {fmt(age['max'], 1)} ms; "
              f"{sim['fields']} fields, interval max {fmt(sim['field_interval_ms']['max'], 3)} ms",
              status(age["max"] < 1000.0 / 12), p.command("flythrough_simulated"))


def stereo_pipeline(p):
    p.group = "Real-time pipeline and output"
    st = p.load("flythrough_stereo.json")
    pairs = [(p.load(f"flythrough_rate_stereo_{i}.json"), p.load(f"flythrough_rate_mono_{i}.json"))
             for i in (1, 2, 3)]
    pairs = [(a, b) for a, b in pairs if a and b]
    if not st:
        return
    cmd = p.command("flythrough_stereo")
    eye = st.get("stereo", {})
    size = f"{eye.get('eye_width', '?')}×{eye.get('eye_height', '?')}"
    load = p.loads.get("flythrough_stereo")
    at = f"; load average {fmt(load, 1)} as it started" if load is not None else ""
    p.row(f"Stereo pipeline on the wall clock, {fmt(st['elapsed_s'], 0)} s, {size} per eye side "
          f"by side, {eye.get('separation_m', '?')} m between the eyes, renderer thread: missed "
          "field deadlines", "0",
          f"{st['missed_deadlines']} of {st['fields']} fields{at}; field interval max "
          f"{fmt(st['field_interval_ms']['max'], 1)} ms",
          status(st["missed_deadlines"] == 0), cmd)
    if pairs:
        s_fps = [a["render_fps"] for a, b in pairs]
        m_fps = [b["render_fps"] for a, b in pairs]
        p.row(f"Render rate of the stereo pair (left eye cast, right eye reprojected) against "
              f"mono, same renderer thread and scenario, {fmt(pairs[0][0]['elapsed_s'], 0)} s "
              f"runs in turn", "—",
              f"mono / pair {spread(ratios(m_fps, s_fps), 2, '×')}; "
              f"{spread(s_fps, 1, ' fps')} against {spread(m_fps, 1, ' fps')}", NO_TARGET,
              p.command("flythrough_rate_stereo_1") + " and " +
              p.command("flythrough_rate_mono_1") + ", three times each in turn")
    right = st["right_eye"]["warp_ms"]
    p.row("Field time per eye, p50 / p99 (fit, check, warp; auto model)", "—",
          f"left {fmt(st['warp_ms']['p50'], 2)} / {fmt(st['warp_ms']['p99'], 2)} ms, right "
          f"{fmt(right['p50'], 2)} / {fmt(right['p99'], 2)} ms", NO_TARGET, cmd)
    vd = st["vertical_disparity_px"]
    p.row("Vertical disparity between the eyes (rows), max over the run: as shown / of the two "
          "quadratic fits", "≤ 0.25 rows",
          f"{fmt(vd['max'], 3)} / {fmt(st['fit_vertical_disparity_px']['max'], 3)} rows; "
          f"{st.get('fields_depth_for_rows', 0)} fields took the depth model for it",
          status(vd["max"] <= 0.25), cmd)


def renderer_process(p):
    p.group = "Real-time pipeline and output"
    doc = p.load("field_clock.json")
    if doc:
        runs = {r["name"]: r for r in doc["runs"]}
        proc, thread = runs.get("process"), runs.get("thread")
        cmd = "`" + doc["command"] + "`"
        if proc:
            s = proc["stats"]
            j = s["field_jitter_ms"]
            restarts = s["renderer_restarts"]
            killed = (f"; renderer killed once halfway, back after {fmt(restarts[0]['recovery_ms'], 0)} ms"
                      if restarts and restarts[0].get("recovery_ms") is not None else "")
            p.row(f"Field clock over {fmt(doc['seconds'] / 60, 0)} min, renderer process on every "
                  "core: missed fields and field-interval jitter p99.9 / max",
                  "0 missed; p99.9 ≤ 0.5 ms, max ≤ 2 ms",
                  f"{s['missed_deadlines']} of {s['fields']} missed; jitter p99 {fmt(j['p99'], 3)}, "
                  f"p99.9 {fmt(j['p99.9'], 3)}, max {fmt(j['max'], 3)} ms{killed}",
                  status(s["missed_deadlines"] == 0 and j["p99.9"] <= 0.5 and j["max"] <= 2.0), cmd)
            p.row("Field process memory over the same run (resident, at 1 min and at the end)",
                  "flat", f"{fmt(proc['rss_kb_at_60s'] / 1024, 1)} MiB → "
                  f"{fmt(proc['rss_kb_at_end'] / 1024, 1)} MiB",
                  status(proc["rss_kb_at_end"] <= proc["rss_kb_at_60s"] * 1.05 + 1024), cmd)
        if proc and thread:
            a, b = proc["stats"], thread["stats"]
            p.row("Render rate: renderer process on every core against a renderer thread on all "
                  "cores but one (same run length, no kill for the thread)", "—",
                  f"{fmt(a['render_fps'], 1)} against {fmt(b['render_fps'], 1)} fps "
                  f"({fmt(a['render_fps'] / b['render_fps'], 2)}×); thread: "
                  f"{b['missed_deadlines']} missed, jitter max {fmt(b['field_jitter_ms']['max'], 1)} ms",
                  NO_TARGET, cmd)
    doc = p.load("renderer_restart.json")
    if doc:
        cmd = "`" + doc["command"] + "`"
        for label, rows in doc["maps"].items():
            rec = [r["recovery_ms"] for r in rows if r["recovery_ms"] is not None]
            if not rec:
                continue
            missed = [r["missed_deadlines"] for r in rows]
            p.row(f"Renderer process killed mid-run, {label}: from the death noticed to the first "
                  "new frame shown; fields missed", "0 missed",
                  f"{spread(rec, 0, ' ms')}; missed per run {', '.join(str(m) for m in missed)}",
                  status(sum(missed) == 0), cmd)
    doc = p.load("io_check_realtime.json")
    if doc:
        w = doc["wake_lateness_ms"]
        p.row("Field clock alone at SCHED_FIFO, nothing else in the loop (what the machine "
              "allows): wake lateness p99 / p99.9 / max; fields more than a period late", "—",
              f"{fmt(w['p99'], 3)} / {fmt(w.get('p99.9', float('nan')), 3)} / {fmt(w['max'], 3)} ms; "
              f"{doc['missed_deadlines']} of {doc['fields']}", NO_TARGET,
              p.command("io_check_realtime"))


def cigi(p):
    """cigi_bench.json (scripts/bench-cigi.sh): host message to field over loopback, with and
    without a flood, and the decoder's and session's rates."""
    p.group = "Real-time pipeline and output"
    doc = p.load("cigi_bench.json")
    if not doc:
        return
    cmd = "`" + doc["command"] + "`"
    period = doc["field_period_ms"]
    for name, label in (("steady", "a 60 Hz host"), ("flood", "the same host plus a flood of "
                                                      f"{fmt(doc['runs'].get('flood', {}).get('host', {}).get('flood_per_second', 0), 0)} "
                                                      "messages a second")):
        r = doc["runs"].get(name)
        if not r:
            continue
        d, late, c = r["host"]["step_to_field_ms"], r["lateness_ms"], r["cigi"]
        stamped = r["host"].get("kernel_arrival_stamps", False)
        read = r["host"].get("step_to_field_read_ms")
        arrival = ("the kernel's arrival stamp of the Start of Frame of the first field that "
                   "applies it" if stamped else
                   "the Start of Frame of the first field that applies it")
        read_text = (f"; the host program read it at {fmt(read['p50'], 2)} / "
                     f"{fmt(read['p99'], 2)} ms" if stamped and read else "")
        p.row(f"CIGI over loopback, {label}: an Entity Control change to {arrival}, "
              "p50 / p99 / max (the field's hand-off follows by its lateness, p50 / p99); "
              "fields missed",
              f"≤ 1 field period ({fmt(period, 2)} ms); 0 missed",
              f"{fmt(d['p50'], 2)} / {fmt(d['p99'], 2)} / {fmt(d['max'], 2)} ms over "
              f"{r['host']['steps_seen']} changes (+ {fmt(late['p50'], 2)} / "
              f"{fmt(late['p99'], 2)} ms){read_text}; {r['missed_deadlines']} of {r['fields']} missed; "
              f"{c['datagrams']} datagrams, longest poll {fmt(c['max_poll_ms'], 2)} ms"
              + (f", at most {c['max_poll_datagrams']} datagrams in one field (each field "
                 "drains the socket)" if "max_poll_datagrams" in c else
                 f", {c['capped_polls']} fields at the 256-datagram cap"),
              status(d["p99"] <= period and r["missed_deadlines"] == 0), cmd)
    dec, ses = doc.get("decode_packets_per_second"), doc.get("session_datagrams_per_second")
    if dec and ses:
        p.row("CIGI decoding: packets a second (a six-packet host message); datagrams a second "
              "a session receives, decodes and applies from a loopback socket", "—",
              f"{spread([x / 1e6 for x in dec], 1, ' M')}; {spread([x / 1e3 for x in ses], 0, ' k')}",
              NO_TARGET, cmd)


def io_layer(p):
    p.group = "Real-time pipeline and output"
    doc = p.load("io_check.json")
    if not doc:
        return
    iv = doc["field_interval_ms"]
    p.row("Field clock alone (test pattern, null sink): missed deadlines", "0",
          f"{doc['missed_deadlines']} of {doc['fields']} fields; interval p50 / p99 / max "
          f"{fmt(iv['p50'], 3)} / {fmt(iv['p99'], 3)} / {fmt(iv['max'], 3)} ms",
          status(doc["missed_deadlines"] == 0), p.command("io_check"))
    doc = p.load("io_check_y4m.json")
    if doc:
        w = doc["sink_write_ms"]
        p.row("Y4M sink at 720×486 UYVY: time to write a field, p50 / p99 / max; missed deadlines",
              "0 missed", f"{fmt(w['p50'], 3)} / {fmt(w['p99'], 3)} / {fmt(w['max'], 3)} ms; "
              f"{doc['missed_deadlines']} of {doc['fields']} fields missed",
              status(doc["missed_deadlines"] == 0), p.command("io_check_y4m"))


def objects(p):
    """objects_bench.json (bench-objects): the fast caster over a populated Puget Sound against
    the same view without objects; its objects against the reference caster's; memory."""
    p.group = "Voxel objects"
    doc = p.load("objects_bench.json")
    if not doc:
        return
    cmd = p.command("objects_bench")
    frames = {f["caster"]: f for f in doc.get("frames", [])}
    mem, own = doc["memory_shared"], doc["memory_own"]
    img = doc["image"].replace("x", "×")
    auto, single = frames.get("fast levels auto"), frames.get("fast levels 0")
    if auto and single:
        ra = ratios(auto["with_ms"], auto["without_ms"])
        r0 = ratios(single["with_ms"], single["without_ms"])
        p.row(f"Fast caster with a populated world / the same view without objects: Puget Sound, "
              f"{mem['objects']} objects (10,000 trees, 300 houses, 20 vehicles), the demo view "
              f"25 m above the ground ({fmt(100 * auto['object_pixel_fraction'], 1)} % of pixels "
              f"objects), {img}, 1 thread", "≤ 1.3×",
              f"levels auto {spread(ra, 2, '×')} ({spread(auto['with_ms'], 0, ' ms')} vs "
              f"{spread(auto['without_ms'], 0, ' ms')}); levels 0 {spread(r0, 2, '×')}; frames "
              "taken in turn", status(statistics.median(ra) <= 1.3), cmd)
    err = {e["caster"]: e for e in doc.get("error", [])}
    if err:
        e = doc["error_image"].replace("x", "×")
        parts = []
        for name in ("fast levels 0", "fast levels auto"):
            if name in err:
                r = err[name]
                parts.append(f"{name[5:]}: ids differ on {r['ids_differ']} of "
                             f"{r['object_pixels']} object pixels "
                             f"({fmt(100 * r['ids_differ'] / max(1, r['object_pixels']), 3)} %), "
                             f"colour error {fmt(r['mae_pct'], 3)} %")
        p.row(f"The fast caster's objects against the reference caster's, same view, {e}", "—",
              "; ".join(parts), NO_TARGET, cmd)
    sw = doc.get("splat_vs_walk")
    if sw:
        p.row(f"The object pass with near boxes splatted (each cell holding an entry projected on "
              f"its own, nearest first) vs every box walked by every pixel of its footprint, same "
              f"terrain image, {img}, 1 thread", "—",
              f"{spread(ratios(sw['walk_ms'], sw['splat_ms']), 2, '×')} faster "
              f"({spread(sw['splat_ms'], 0, ' ms')} vs {spread(sw['walk_ms'], 0, ' ms')}); "
              f"{sw['splatted']} of {sw['boxes']} boxes splatted ({sw['columns']} columns); "
              f"images {'identical' if sw['identical'] else 'differ'}",
              NO_TARGET, cmd)
    pv = doc.get("pass_vs_per_pixel")
    if pv:
        e = doc["error_image"].replace("x", "×")
        p.row(f"Objects by their screen footprint vs every pixel's ray through the object grid, "
              f"same terrain image, {e}, 1 thread", "—",
              f"{spread(ratios(pv['per_pixel_ms'], pv['pass_ms']), 1, '×')} faster "
              f"({spread(pv['pass_ms'], 1, ' ms')} vs {fmt(statistics.median(pv['per_pixel_ms']), 0)} "
              f"ms); images {'identical' if pv['identical'] else 'differ'}", NO_TARGET, cmd)
    tb = p.load("truth_bench.json")
    if tb:
        f, r = tb["fast_ms"], tb["reference_ms"]
        p.row(f"Exact ground truth of one {tb['size'].replace('x', '×')} field, the demo's low pass "
              f"over the forest ({fmt(tb['objects_listed_per_field'], 0)} objects listed, "
              f"{fmt(tb['unoccluded_px_per_field'], 0)} unoccluded pixels a field): processor "
              "time of one thread, the truth's fast path (solid-voxel table walk, rays over the "
              "box's projected hull) against its reference twin; lines compared byte for byte",
              "≤ 16.7 ms (one field); 0 lines differing",
              f"{fmt(f['mean'], 2)} ± {fmt(f['sd'], 2)} ms vs {fmt(r['mean'], 2)} ± "
              f"{fmt(r['sd'], 2)} ms (mean ± sd of {f['n']}: {tb['fields']} fields × "
              f"{tb['repeat']}); {tb['mismatched_lines']} lines differing",
              status(f["mean"] <= 1001 / 60 and tb["mismatched_lines"] == 0),
              p.command("truth_bench"))
    fly = p.load("flythrough_truth.json")
    if fly and "truth" in fly:
        t = fly["truth"]
        p.row(f"Ground truth on the wall clock: flythrough --truth at {fly['width']}×"
              f"{fly['height']}, the demo scene's low pass over the forest, {fly['fields']} fields: "
              "lines written (one per field, in order), fields written late (shown objects only) "
              "and lost (index and instant only)", "0 lost",
              f"{t['fields']} lines, {t.get('late_fields', 0)} late, {t.get('lost_fields', 0)} "
              f"lost; {fly['missed_deadlines']} missed field deadlines; the run completes",
              status(t.get("lost_fields", 0) == 0 and t["fields"] == fly["fields"]),
              p.command("flythrough_truth"))
    p.row(f"Memory per placed object (stick table + cell references + boxes), shared stick "
          f"table vs every copy its own lists, {mem['objects']} objects", "—",
          f"{fmt(mem['bytes_per_object'], 0)} B vs {fmt(own['bytes_per_object'], 0)} B "
          f"({mem['stick_lists']} vs {own['stick_lists']} stick lists; table "
          f"{fmt(mem['table_bytes'] / 1e3, 1)} kB vs {fmt(own['table_bytes'] / 1e6, 1)} MB)",
          NO_TARGET, cmd)


# --- the page ------------------------------------------------------------------------------------

def render(data_dir):
    p = Page(data_dir)
    casters(p)
    renderer(p)
    span(p)
    appearance(p)
    callgrind(p)
    warp(p)
    depth_warp(p)
    warp_eval(p)
    moving_targets(p)
    stereo(p)
    pipeline(p)
    stereo_pipeline(p)
    renderer_process(p)
    cigi(p)
    io_layer(p)
    terrain_db(p)
    paged_flight(p)
    detail(p)
    insets(p)
    objects(p)
    m = p.load("machine.json") or {}
    out = ["# Measured results", "",
           "<!-- Generated by scripts/results.py from docs/results/data/; do not edit by hand. -->",
           "",
           "One row per claim: what is measured, the target where there is one, the value, "
           "whether the target is met, and the command that measured it (programs in "
           "`build/release/bin/`, built by `cmake --preset release && cmake --build --preset "
           "release`). `scripts/results.sh` runs every command below on this machine (adding the "
           "options that write each program's JSON) and regenerates this page and its data "
           "(`docs/results/data/`); `scripts/results.py` "
           "regenerates the page from the data, and a test (`results.page_matches_data`) fails "
           "when the two disagree.", ""]
    if m:
        out += [f"**Machine:** {m.get('cpu', '?')}, {m.get('cores', '?')} cores "
                f"({m.get('simd', '?')}), {m.get('memory_gib', '?')} GiB, {m.get('os', '?')}, "
                f"{m.get('compiler', '?')}; Release build, no `-march` (vector kernels are "
                f"picked at run time); revision {m.get('revision', '?')}, {m.get('date', '?')}. "
                f"The machine is shared (load average {load_range(p, m)} as the commands "
                "started), so single times are noisy: values are medians with their range over "
                "the runs, and ratios pair runs taken in turn where the program does.", ""]
    met = sum(1 for _, r in p.rows if r[3] == MET)
    missed = [r[0] for _, r in p.rows if r[3] == NOT_MET]
    out += [f"{len(p.rows)} claims: {met} targets met, {len(missed)} not met (**not met** below), "
            f"{len(p.rows) - met - len(missed)} without a target.", ""]
    groups = []
    for group, _ in p.rows:
        if group not in groups:
            groups.append(group)
    for group in groups:
        out += [f"## {group}", "", "| what | target | value | status | command |",
                "| --- | --- | --- | --- | --- |"]
        for g, r in p.rows:
            if g == group:
                out.append("| " + " | ".join(r) + " |")
        out.append("")
        for g, title, text, table in p.sections:
            if g == group:
                out += [f"### {title}", "", text, "", table, ""]
    out += ["## Elsewhere", "",
            "Experiments that were measured and not kept are in the design notes' "
            "\"Alternatives considered\" sections (`docs/design/`); how each part works is in "
            "its design note. Earlier figures are in this page's history.", ""]
    return "\n".join(out), len(p.rows)


def load_range(p, m):
    loads = list(p.loads.values()) or [m.get("load_average_at_start", 0)]
    return f"{fmt(min(loads), 1)}–{fmt(max(loads), 1)}" if len(loads) > 1 else fmt(loads[0], 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true",
                    help="compare the page with what the data give; exit 1 if they differ")
    ap.add_argument("--data", default=DATA, help="data folder (default docs/results/data)")
    ap.add_argument("--out", default=PAGE, help="page to write or check (default docs/results.md)")
    args = ap.parse_args()
    page, claims = render(args.data)
    if args.check:
        try:
            with open(args.out, encoding="utf-8") as f:
                current = f.read()
        except OSError as e:
            print(f"results.py: {args.out}: {e.strerror}", file=sys.stderr)
            return 1
        if current != page:
            print(f"results.py: {args.out} does not match docs/results/data/; run "
                  "scripts/results.py to regenerate it", file=sys.stderr)
            return 1
        print(f"results.py: {args.out} matches the data")
        return 0
    with open(args.out, "w", encoding="utf-8") as f:
        f.write(page)
    print(f"results.py: wrote {args.out} ({claims} claims)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
