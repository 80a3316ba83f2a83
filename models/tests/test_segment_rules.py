"""The offline scorer of instance-dropping rules reads what `phyllo eval --segments` writes."""

from phyllo_train.experiments.segment_rules import dropped_by, main, read_rows, score

HEADER = "image\ttruth\tpredicted\tsegment\tkind\tarea\tscore\tmax_contact\ttotal_contact\tneighbour_area\n"


def write(tmp_path, lines):
    path = tmp_path / "segments.tsv"
    path.write_text(HEADER + "".join(line + "\n" for line in lines))
    return path


def test_dropping_a_weak_split_piece_fixes_its_image_only(tmp_path, capsys):
    path = write(tmp_path, [
        # Image a: two leaves, one split in two (predicted 3); the piece is weak and borders its leaf.
        "a\t2\t3\t1\tfound\t300\t0.9\t12\t12\t80",
        "a\t2\t3\t2\tpartner\t200\t0.8\t0\t0\t0",
        "a\t2\t3\t3\tsplit\t80\t0.25\t12\t12\t300",
        # Image b: right count; a weak leaf touching a larger one, wrongly dropped by the rule.
        "b\t2\t2\t1\tfound\t400\t0.9\t5\t5\t60",
        "b\t2\t2\t2\tfound\t60\t0.28\t5\t5\t400",
    ])
    rows = read_rows([path])
    assert score(rows, lambda r: False)["exact"] == 50.0
    m = score(rows, dropped_by(0.3, 10))
    assert (m["exact"], m["dropped_split"], m["dropped_other"]) == (100.0, 1, 0)
    m = score(rows, dropped_by(0.3, 0))
    assert (m["exact"], m["bias"], m["dropped_split"], m["dropped_other"]) == (50.0, -0.5, 1, 1)
    main([str(path)])
    out = capsys.readouterr().out
    assert "| off |  | 2 | 50.0 % |" in out
    assert "| 0.3 | 10 | 2 | 100.0 % |" in out
