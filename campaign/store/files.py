"""Files written atomically and read back: Parquet with the campaign metadata in its schema,
text, SHA-256 digests, the engine version (used by :class:`campaign.store.directory.CampaignDir`,
which alone decides which files a campaign directory holds).

Every file is written under a temporary name next to its target and moved into place with
``os.replace``, so a crash or a kill leaves either the old file or the new one, never a torn
one.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import secrets
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

__all__ = ["METADATA_KEY", "UNKNOWN_VERSION", "engine_version", "read_metadata", "sha256_of",
           "write_parquet", "write_text"]

#: Schema-metadata key of the campaign metadata in every Parquet file.
METADATA_KEY = b"fdd_campaign"


#: The engine version of a source tree that is not installed (no package metadata).
UNKNOWN_VERSION = "0+unknown"


@functools.cache
def engine_version() -> str:
    """The installed fdd-campaign version (:data:`UNKNOWN_VERSION` when running from a
    source tree that is not installed): the version of the code this process runs, read
    from the package metadata once (each Parquet file and manifest write names it)."""
    try:
        return version("fdd-campaign")
    except PackageNotFoundError:
        return UNKNOWN_VERSION


def temporary_name(path: Path) -> Path:
    """A fresh hidden name next to *path* (``.NAME.PID.RANDOM.tmp``), not created: the
    writer creates it, with the mode the umask gives."""
    return path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"


def atomic_write_bytes(path: Path, write) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_name(path)
    try:
        write(str(tmp))
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


#: Rows of a row group when the writer is not told (pyarrow's default, 1 Mi rows).
DEFAULT_ROW_GROUP_ROWS = 1024 * 1024


def write_parquet(df: pd.DataFrame, path: Path, config_json: str, *,
                  row_group_rows: int | None = None, packed: tuple[str, ...] = (),
                  **extra) -> None:
    """Write *df* to *path* atomically with the campaign metadata in the schema, in row
    groups of *row_group_rows* rows (default :data:`DEFAULT_ROW_GROUP_ROWS`): the table of
    one frame (:func:`write_parquet_blocks`)."""
    write_parquet_blocks([df], path, config_json, rows=len(df),
                         row_group_rows=row_group_rows or DEFAULT_ROW_GROUP_ROWS,
                         packed=packed, **extra)


#: Compression of the columns a writer names *packed* (bytes packed by the engine itself,
#: e.g. :data:`reports.scoring.alarm_steps.ALARM_STEPS_COLUMN`): zstd takes them to 0.77 of snappy's
#: size (21.3 against 27.6 kB on addsafe-mc's shards, seed 4242); the other columns keep
#: pyarrow's default, snappy.
PACKED_COMPRESSION = "zstd"


def _writer_options(schema: pa.Schema, packed: tuple[str, ...]) -> dict:
    """ParquetWriter options: pyarrow's defaults, except that the *packed* columns of
    *schema* are compressed with :data:`PACKED_COMPRESSION` and carry no min/max statistics
    (of packed bytes they say nothing)."""
    packed = [name for name in schema.names if name in packed]
    if not packed:
        return {}
    return {"compression": {name: PACKED_COMPRESSION if name in packed else "snappy"
                            for name in schema.names},
            "write_statistics": [name for name in schema.names if name not in packed]}


def write_parquet_blocks(frames, path: Path, config_json: str, *, rows: int,
                         row_group_rows: int, before_commit=None,
                         packed: tuple[str, ...] = (), **extra) -> None:
    """Write the table whose rows *frames* (DataFrames of the same columns and types) give
    in order, *rows* of them in all, to *path* atomically with the campaign metadata in the
    schema, in row groups of *row_group_rows* rows, as the frames come: memory holds a row
    group and a frame, whatever the size of the table, and the row groups do not depend on
    how the rows are cut into frames. *before_commit*, called once every frame is written
    and before the file takes its name, may refuse the table by raising (nothing is
    written then). The *packed* columns are written as :func:`_writer_options` says."""
    meta = {METADATA_KEY: json.dumps({
        "engine_version": engine_version(), "rows": int(rows),
        "config": json.loads(config_json), **extra,
    }).encode()}

    def write(tmp) -> None:
        writer = schema = None
        pending: list[pa.Table] = []
        held = written = 0

        def flush(n: int) -> None:
            nonlocal pending, held, written
            table = pa.concat_tables(pending)
            writer.write_table(table.slice(0, n), row_group_size=row_group_rows)
            rest = table.slice(n)
            pending, held, written = ([rest] if len(rest) else []), len(rest), written + n

        try:
            for frame in frames:
                table = pa.Table.from_pandas(frame, preserve_index=False)
                if writer is None:
                    schema = table.schema.with_metadata({**(table.schema.metadata or {}),
                                                         **meta})
                    writer = pq.ParquetWriter(tmp, schema, **_writer_options(schema, packed))
                pending.append(table.cast(schema))
                held += len(table)
                while held >= row_group_rows:
                    flush(row_group_rows)
            if writer is None:
                raise ValueError("write_parquet_blocks: no frame to write (not even an empty "
                                 "one with the columns)")
            if held:
                flush(held)
        finally:
            if writer is not None:
                writer.close()
        if written != rows:
            raise ValueError(f"write_parquet_blocks: {written} rows written, {rows} announced")
        if before_commit is not None:
            before_commit()

    atomic_write_bytes(Path(path), write)


def read_metadata(path: Path) -> dict:
    """The campaign metadata stored in a Parquet file by :func:`write_parquet`."""
    meta = pq.read_schema(path).metadata or {}
    return json.loads(meta.get(METADATA_KEY, b"{}"))


def write_text(path: Path, text: str) -> None:
    atomic_write_bytes(Path(path), lambda tmp: Path(tmp).write_text(text))


def sha256_of(path: Path) -> str:
    """The SHA-256 digest of the file *path* (hex)."""
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()
