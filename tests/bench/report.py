#!/usr/bin/env python3
"""Prints run.sh's one markdown table from the files it measured:

    report.py --bench bench.json [--peer peer.json] [--training training.json] [--command "..."]

bench.json: Google Benchmark's JSON of ism-bench (medians of the repetitions); peer.json: the
output of pcl-ism-peer --json; training.json: {"seconds": ..., "scans": ...} from timing ism-train.
A figure that was not measured is printed as "not measured" with the reason, never made up.
"""
import argparse
import json
import math


def load(path):
    if not path:
        return None
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


class Bench:
    """Medians by run name ("frame/describe/threads:1"), in ms, plus the counters."""

    def __init__(self, doc):
        self.context = doc.get("context", {})
        self.runs = {}
        for b in doc.get("benchmarks", []):
            if b.get("error_occurred"):
                self.runs.setdefault(b["run_name"], {"error": b.get("error_message", "error")})
                continue
            is_median = b.get("run_type") == "aggregate" and b.get("aggregate_name") == "median"
            # Benchmarks with one repetition report their single run instead of aggregates.
            if is_median or (b.get("run_type") == "iteration" and b["run_name"] not in self.runs):
                self.runs[b["run_name"]] = b

    def find(self, prefix):
        for name, run in self.runs.items():
            if name == prefix or name.startswith(prefix + "/"):
                return run
        return None

    def ms(self, prefix):
        run = self.find(prefix)
        if run is None or "error" in run:
            return None
        scale = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}[run.get("time_unit", "ns")]
        return run["real_time"] * scale

    def counter(self, prefix, name):
        run = self.find(prefix)
        return None if run is None or "error" in run else run.get(name)

    def error(self, prefix):
        run = self.find(prefix)
        return run.get("error") if run else "not run"


def fmt(v, digits=1, unit=""):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "not measured"
    return f"{v:,.{digits}f}{unit}"


def pct(a, b):
    if a is None or b is None or b == 0:
        return None
    return 100.0 * (a - b) / b


def rate(s):
    if not s:
        return "not measured"
    return f'{100 * s["rate"]:.1f}% (TP {s["tp"]}, FP {s["fp"]}, FN {s["fn"]} of {s["objects"]})'


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bench", required=True)
    ap.add_argument("--peer")
    ap.add_argument("--peer-status", default="", help="why the peer has no output, when it has none")
    ap.add_argument("--training")
    ap.add_argument("--command", default="")
    args = ap.parse_args()

    doc = load(args.bench)
    if doc is None:
        raise SystemExit(f"report.py: {args.bench} is missing or not JSON")
    bench = Bench(doc)
    peer = load(args.peer)
    training = load(args.training)
    procs = int(bench.context.get("processors", "1"))
    all_t = procs
    rows = []

    def row(measure, one="", many="", grpc="", overhead="", pcl="", ratio="", r=""):
        rows.append([measure, one, many, grpc, overhead, pcl, ratio, r])

    # An organized frame's keypoints come before its normals (computed only near them).
    stages = [("downsample", "voxel grid"), ("smooth", "MLS"), ("gravity", "floor, walls, up"),
              ("keypoints", "contours / boundary"), ("normals", "PCA"),
              ("describe", "SHOT + LRF"), ("activate", "codebook"), ("vote", "4 Hough spaces"),
              ("hypotheses", "peaks, support, boxes")]
    for key, what in stages:
        one, many = bench.ms(f"frame/{key}/threads:1"), bench.ms(f"frame/{key}/threads:{all_t}")
        if one is None and many is None and bench.find(f"frame/{key}") is None:
            continue
        row(f"stage {key} ({what}), ms", fmt(one), fmt(many))
    one, many = bench.ms("frame/verify10/threads:1"), bench.ms(f"frame/verify10/threads:{all_t}")
    if one is not None or many is not None:
        n = bench.counter("frame/verify10/threads:1", "candidates")
        row(f"stage verify ({n:.0f} most confident candidates' fit; issue 15: 10 in 20 ms), ms" if n else
            "stage verify (no candidates), ms", fmt(one), fmt(many))
    one, many = bench.ms("frame/recognize/threads:1"), bench.ms(f"frame/recognize/threads:{all_t}")
    g1, gn = bench.ms("grpc/recognize/threads:1"), bench.ms(f"grpc/recognize/threads:{all_t}")
    o1, on = pct(g1, one), pct(gn, many)
    grpc_cell = f"{fmt(g1)} / {fmt(gn)}" if (g1 or gn) else "not measured: " + str(bench.error("grpc/recognize"))
    row("**one frame, whole recognition**, ms", f"**{fmt(one)}**", f"**{fmt(many)}**", grpc_cell,
        f"{fmt(o1, 1, '%')} / {fmt(on, 1, '%')}")

    if peer and "summary" in peer:
        s = peer["summary"]
        names = ", ".join(x["scene"] for x in peer["scenes"])
        ours_ms, pcl_ms = s.get("ours_median_ms"), s.get("pcl_median_ms")
        speed = f"{pcl_ms / ours_ms:.1f}x slower" if ours_ms and pcl_ms else "not measured"
        pcl_cell = fmt(pcl_ms)
        if s.get("pcl_failures"):
            pcl_cell += f' ({s["pcl_failures"]} scene(s) failed)'
        p = peer["params"]
        row(f"annotated scenes ({names}), median per scene, {p['threads']} threads, ms", "", fmt(ours_ms), "", "",
            pcl_cell, speed,
            f'ours {rate(s["ours"])}; PCL strongest peak per category {rate(s["pcl_top_peak"])}; '
            f'PCL every peak {rate(s["pcl_all_peaks"])}')
    else:
        row("annotated scenes: ours vs PCL ISM", "", "", "", "", "not measured: " + (args.peer_status or "no peer output"))

    load_ms = bench.ms("model/load")
    row(f"model load ({bench.counter('model/load', 'bytes') and round(bench.counter('model/load', 'bytes') / 2**20, 1)} MB file), ms",
        fmt(load_ms))
    mem = bench.find("server/memory")
    if mem and "error" not in mem:
        n = int(mem.get("recognitions", 0))
        row("ism-server memory with the default model, VmRSS / VmHWM, MB",
            "", f'{fmt(mem.get("rss_loaded_MB"), 0)} / {fmt(mem.get("hwm_loaded_MB"), 0)}')
        row(f"ism-server memory after {n} recognitions, VmRSS / VmHWM, MB",
            "", f'{fmt(mem.get("rss_after_MB"), 0)} / {fmt(mem.get("hwm_after_MB"), 0)}')
    else:
        row("ism-server memory", "", "not measured: " + str(bench.error("server/memory")))

    if training and training.get("seconds") is not None:
        train_cell = fmt(training["seconds"], 1)
    else:
        train_cell = "not measured" + (f': {training["skipped"]}' if training and training.get("skipped") else "")
    pcl_train, ratio = "", ""
    if peer and "training" in peer:
        t = peer["training"]
        pcl_train = f'{t["train_s"]:.1f} (+{t["scan_s"]:.1f} scanning, {t["scans"]} scans, {t["words"]:,} words)'
        if training and training.get("seconds"):
            ratio = f'{(t["train_s"] + t["scan_s"]) / training["seconds"]:.1f}x'
    row(f"training on the default manifest, {procs} threads, s", "", train_cell, "", "", pcl_train, ratio)

    header = ["measure", "ours, 1 thread", f"ours, {all_t} threads", f"over gRPC, 1 / {all_t} threads",
              f"service overhead, 1 / {all_t} threads", "PCL ISM", "PCL ISM / ours", "recognition rate r = TP / (objects + FP)"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for r in rows:
        print("| " + " | ".join(r) + " |")
    print()
    ctx = bench.context
    reps = next((b.get("repetitions") for b in doc.get("benchmarks", []) if b.get("run_name", "").startswith("frame/")), "?")
    load_avg = ", ".join(f"{x:.1f}" for x in ctx.get("load_avg", []))
    print(f'Frame rows: {ctx.get("scene")} ({ctx.get("scene_points")} points, {ctx.get("scene_keypoints")} described '
          f'keypoints; {ctx.get("scene_note")}), model {ctx.get("model")} ({ctx.get("categories")} categories), '
          f'medians of {reps} repetitions, wall-clock time; {procs} processors, load average at the start {load_avg}. '
          f'gRPC: unary Recognize of the same frame (packed organized cloud as ism-client sends it: xyz, no colour, '
          f'{fmt(bench.counter(f"grpc/recognize/threads:{all_t}", "request_MB"), 1)} MB) to a real ism-server on '
          f'127.0.0.1 started as `ism-server --threads 1 --threads-per-request` the column\'s threads; overhead = gRPC / in process - 1. Server memory: `ism-server` with its defaults.')
    if peer and "params" in peer:
        p = peer["params"]
        sig = ", ".join(f"{k} {v:.3g}" for k, v in peer["training"]["sigmas_m"].items())
        print(f'Annotated scenes: both from the loaded cloud; ours recognize() ({p["ours_strategy"]}, median of '
              f'{p["ours_repeats"]} runs per scene); PCL ISM {p["leaf_m"]:.3g} m voxel grid, normals over '
              f'{p["normal_radius_m"]:.3g} m, keypoint sampling {p["sampling_m"]:.3g} m, 33-d FPFH over '
              f'{p["fpfh_radius_m"]:.3g} m, {p["clusters"]} clusters, sigma = {p["sigma_fraction"]:.3g} x object radius '
              f'({sig} m), findObjects + findStrongestPeaks(10 sigma, sigma) per category'
              f'{", scenes with a floor normal rotated to z up for it" if p.get("align_up") else ""}. '
              f'Rates by the rule of ism-eval real (centroid of support, or PCL\'s peak, within 1/4 of the '
              f'category\'s largest box edge of a true centre).')
    if args.command:
        print(f"Command: `{args.command}`")


if __name__ == "__main__":
    main()
