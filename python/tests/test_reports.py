"""`reducem.convert` reports through the `reducem` logger and the `progress` callback, and
writes nothing to stderr."""

import logging

import pytest

import reducem

STAGES = ["chunk", "strip", "merge", "hierarchy", "write"]


def progress_calls(scan_ply, out, **options):
    calls = []
    reducem.convert(scan_ply, out, progress=lambda *call: calls.append(call), **options)
    return calls


def test_convert_logs_each_stage_and_prints_nothing(scan_ply, tmp_path, caplog, capfd):
    with caplog.at_level(logging.DEBUG, logger="reducem"):
        reducem.convert(scan_ply, tmp_path / "scan.rdm", max_triangles=2000)
    records = [r for r in caplog.records if r.name == "reducem"]
    events = [(r.stage, r.event) for r in records]
    assert [stage for stage, event in events if event == "done"] == STAGES
    for stage in STAGES:
        assert events.index((stage, "start")) < events.index((stage, "done")), stage
    assert all(r.levelno == logging.INFO for r in records if r.event != "progress")
    unit_records = [r for r in records if r.event == "progress"]
    assert unit_records and all(r.levelno == logging.DEBUG for r in unit_records)
    chunks = sum(1 for r in unit_records if r.stage == "strip")
    assert chunks > 1
    assert f"strip: {chunks}/{chunks} chunks" in [r.getMessage() for r in records]
    assert records[-1].getMessage().startswith("run: finished in ")
    assert capfd.readouterr().err == ""


def test_progress_counts_each_stage_once_from_zero_to_its_total(scan_ply, tmp_path):
    calls = progress_calls(scan_ply, tmp_path / "scan.rdm", max_triangles=2000)
    by_stage = {}
    for stage, done, total, unit in calls:
        by_stage.setdefault(stage, []).append((done, total, unit))
    assert list(by_stage) == STAGES
    for stage, reports in by_stage.items():
        total, unit = reports[0][1:]
        assert all((t, u) == (total, unit) for _, t, u in reports), stage
        counts = [done for done, _, _ in reports]
        # Stages that finish chunk by chunk count them one by one; the others all at once.
        expected = list(range(total + 1)) if stage in ("chunk", "strip", "merge") else [0, total]
        assert counts == expected, (stage, counts)
    assert by_stage["strip"][0][1:] == (by_stage["chunk"][0][1], "chunks")
    assert by_stage["write"] == [(0, 3, "sections"), (3, 3, "sections")]


def test_a_resumed_conversion_reports_its_skipped_units(scan_ply, tmp_path):
    out = tmp_path / "scan.rdm"
    reducem.convert(scan_ply, out, max_triangles=2000)
    calls = progress_calls(scan_ply, out, max_triangles=2000)
    (_, _, chunks, _), *_ = calls
    assert calls == [("strip", 0, chunks, "chunks"), ("strip", chunks, chunks, "chunks")]


def test_an_exception_in_progress_reaches_the_caller(scan_ply, tmp_path):
    class Stop(Exception):
        pass

    def stop(stage, done, total, unit):
        raise Stop(stage)

    with pytest.raises(Stop, match="chunk"):
        reducem.convert(scan_ply, tmp_path / "scan.rdm", progress=stop)


def test_progress_must_be_given_by_name(scan_ply, tmp_path):
    with pytest.raises(TypeError):
        reducem.convert(scan_ply, tmp_path / "scan.rdm", print)
