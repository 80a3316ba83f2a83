#!/usr/bin/env python3
"""Runs a real `phyllo serve` on a scratch site, drops a burst of images into
it, waits until every one has a row, stops it with SIGTERM and prints what it
measured as one JSON object (standard library only, so it runs anywhere).

    scripts/serve_burst.py --phyllo BIN [--qemu SYSROOT] --images F... [--n N]

- `--phyllo BIN` is the binary; with `--qemu SYSROOT` it runs under
  `qemu-aarch64 -L SYSROOT` (an ARM build on an x86 machine).
- `--images` are copied in round-robin until `--n` files (default: one each)
  have been dropped. Each copy gets bytes appended after its image data (after
  PNG's IEND or JPEG's EOI, where decoders stop reading), so every file has its
  own hash and is counted, not recorded as a duplicate of an earlier one.
  Dropped names follow the facility's pattern, one plant per source image.
- The daemon runs with the default intake and inference settings (`--config`
  appends TOML), the model it finds itself (beside the binary, or this
  source tree's).

JSON fields: `dropped`, `counted`, `failed` (with `errors`), `exit_code` (0 is
a clean stop), `wall_s` (first drop to last row), `s_per_image`,
`peak_rss_mb` (the serving process's maximum resident set, from wait4; under
qemu it is the emulator's, guest memory included), and `counts`, the leaf
count per source image (its first copy).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def site_config(root: Path, extra: str) -> Path:
    drop, state = root / "drop", root / "state"
    drop.mkdir()
    state.mkdir()
    cfg = root / "phyllo.toml"
    cfg.write_text(f'drop_dir = "{drop}"\ndatabase = "{state / "phyllo.sqlite"}"\n{extra}')
    return cfg


def dropped_name(source: int, suffix: str, copy: int) -> str:
    """`B<source>_<date>_<time>_Vis_SV_108<ext>`: one plant per source image,
    one imaging time per copy, so no two files share a plant and time."""
    day, rest = divmod(copy, 24 * 60)
    hour, minute = divmod(rest, 60)
    return f"B{source:03}_2019-06-{1 + day:02}_{hour:02}-{minute:02}-00_Vis_SV_108{suffix.lower()}"


def stop(proc: subprocess.Popen, grace: float) -> tuple[int, object]:
    """SIGTERM, then wait up to `grace` s (SIGKILL after): exit code, rusage."""
    proc.send_signal(signal.SIGTERM)
    deadline = time.monotonic() + grace
    while time.monotonic() < deadline:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            return os.waitstatus_to_exitcode(status), usage
        time.sleep(0.2)
    proc.kill()
    _, status, usage = os.wait4(proc.pid, 0)
    print(f"phyllo serve did not stop within {grace:.0f} s of SIGTERM", file=sys.stderr)
    return os.waitstatus_to_exitcode(status), usage


def rows(db: Path, sql: str) -> list[tuple]:
    if not db.exists():
        return []
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5) as con:
            return con.execute(sql).fetchall()
    except sqlite3.Error:
        return []  # not created yet, or mid-migration


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--phyllo", required=True, type=Path)
    ap.add_argument("--qemu", metavar="SYSROOT", help="run under qemu-aarch64 -L SYSROOT")
    ap.add_argument("--images", required=True, nargs="+", type=Path)
    ap.add_argument("--n", type=int, default=0, help="files to drop (default: one per image)")
    ap.add_argument("--timeout", type=float, default=3600, help="seconds to wait for every row")
    ap.add_argument("--config", default="", help="TOML appended to the config, e.g. '[inference]\\nworkers = 1'")
    args = ap.parse_args()
    n = args.n or len(args.images)
    cmd = [str(args.phyllo.resolve())]
    if args.qemu:
        cmd = ["qemu-aarch64", "-L", args.qemu] + cmd

    with tempfile.TemporaryDirectory(prefix="phyllo-burst-") as tmp:
        root = Path(tmp)
        cfg = site_config(root, args.config.replace("\\n", "\n"))
        db = root / "state" / "phyllo.sqlite"
        log = open(root / "serve.log", "wb")
        proc = subprocess.Popen(cmd + ["serve", "--config", str(cfg)], stdout=log, stderr=subprocess.STDOUT)
        # Ready once the database exists and its schema is in.
        t_start = time.monotonic()
        while not rows(db, "SELECT 1 FROM images LIMIT 1") and not rows(db, "SELECT COUNT(*) FROM meta"):
            if proc.poll() is not None or time.monotonic() - t_start > 600:
                print((root / "serve.log").read_text(errors="replace"), file=sys.stderr)
                print("phyllo serve did not start", file=sys.stderr)
                proc.kill()
                return 1
            time.sleep(0.5)

        staging = root / "staging"
        staging.mkdir()
        first_names = {}
        t0 = time.monotonic()
        for i in range(n):
            k = i % len(args.images)
            src = args.images[k]
            name = dropped_name(k, src.suffix, i // len(args.images))
            first_names.setdefault(src.name, name)
            tmp_file = staging / name
            shutil.copyfile(src, tmp_file)
            with open(tmp_file, "ab") as f:
                f.write(f"phyllo-burst-{i}".encode())
            os.rename(tmp_file, root / "drop" / name)  # appears whole, as a camera PC's move does

        done = 0
        while time.monotonic() - t0 < args.timeout and proc.poll() is None:
            done = rows(db, "SELECT COUNT(*) FROM images WHERE state IN ('counted', 'failed')")
            done = done[0][0] if done else 0
            if done >= n:
                break
            time.sleep(0.5)
        wall = time.monotonic() - t0

        code, usage = stop(proc, 300 if args.qemu else 60)
        log.close()
        counts = dict(rows(db, "SELECT i.path, o.leaf_count FROM images i JOIN observations o ON o.image_id = i.id"))
        errors = [e for (e,) in rows(db, "SELECT error FROM images WHERE state = 'failed'")]
        out = {
            "command": " ".join(cmd),
            "dropped": n,
            "counted": len(counts),
            "failed": len(errors),
            "errors": errors[:5],
            "exit_code": code,
            "wall_s": round(wall, 1),
            "s_per_image": round(wall / max(1, len(counts)), 2),
            "peak_rss_mb": round(usage.ru_maxrss / 1024, 1),
            "counts": {src: counts.get(name) for src, name in first_names.items()},
        }
        print(json.dumps(out))
        if code != 0 or done < n:
            print((root / "serve.log").read_text(errors="replace")[-4000:], file=sys.stderr)
        return 0 if code == 0 and len(counts) == n else 1


if __name__ == "__main__":
    sys.exit(main())
