"""The calibration store: every record of every robot in one database, SQLite (one file) or PostgreSQL
(a server, for a fleet), through SQLAlchemy Core.

Tables: ``robots`` (name, serial, model_hash; one row per (name, serial)), ``records`` (the robot, kind,
time, verdict, note, the whole :class:`Record` as JSON, and its model hash), ``parameters`` and ``inputs``
(rows of a record, for queries), ``schema_version``. The schema is versioned: :data:`MIGRATIONS`, in order,
are applied in one transaction when a store is opened; a store newer than this kincal is refused.

Every write is one transaction, serialised: SQLite by ``BEGIN IMMEDIATE`` (write-ahead log, 60 s busy
timeout: a second writer waits), PostgreSQL by a transaction-level advisory lock. Two processes writing at
once both get their records; a process killed mid-write leaves nothing of the record it was writing.

The robot's nominal model: each record keeps its own model hash; ``robots.model_hash`` is the latest one
recorded. A record whose model hash differs from it (same name and serial: the robot's nominal model was
changed, e.g. a new robot file) is recorded and flagged (``records.model_changed``, :meth:`Store.model_changes`);
the history says so beside it. Events carry no model and are never flagged.
"""
from __future__ import annotations

import dataclasses
import importlib.util
import json
import os
import sqlite3
from contextlib import contextmanager
from pathlib import Path
from urllib.parse import quote
from typing import Any, Callable, Iterator

from ..errors import KincalError
from .records import Identity, Record, not_in_future

SCHEMA_VERSION = 3
BUSY_TIMEOUT_S = 60.0  # SQLite: how long a writer waits for another's transaction
LOCK_KEY = 0x6B696E63616C  # PostgreSQL advisory lock of the store's writers ("kincal")
POSTGRES_HINT = "pip install 'kincal[postgres]'"


class StoreError(KincalError):
    """The calibration store cannot be opened or read (a missing folder, a newer schema, no driver)."""


def _tables(version: int):
    """The tables as they are at schema ``version`` (a MetaData of its own), for migrations and queries."""
    import sqlalchemy as sa

    md = sa.MetaData()
    sa.Table("schema_version", md, sa.Column("version", sa.Integer, nullable=False))
    sa.Table("robots", md, sa.Column("id", sa.Integer, primary_key=True),
             sa.Column("name", sa.String(200), nullable=False), sa.Column("serial", sa.String(200), nullable=False),
             sa.Column("model_hash", sa.String(64), nullable=False),
             sa.UniqueConstraint("name", "serial", name="robots_name_serial"))
    extra = _v3_columns() if version >= 3 else []
    sa.Table("records", md, sa.Column("id", sa.Integer, primary_key=True),
             sa.Column("robot_id", sa.Integer, sa.ForeignKey("robots.id"), nullable=False),
             sa.Column("kind", sa.String(20), nullable=False), sa.Column("time", sa.String(32), nullable=False),
             sa.Column("verdict", sa.String(40)), sa.Column("note", sa.Text, nullable=False),
             sa.Column("payload", sa.JSON, nullable=False), *extra)
    sa.Table("parameters", md, sa.Column("id", sa.Integer, primary_key=True),
             sa.Column("record_id", sa.Integer, sa.ForeignKey("records.id"), nullable=False),
             sa.Column("name", sa.String(200), nullable=False), sa.Column("value", sa.Double, nullable=False),
             sa.Column("sigma", sa.Double), sa.Column("identifiable", sa.Boolean, nullable=False))
    sa.Table("inputs", md, sa.Column("id", sa.Integer, primary_key=True),
             sa.Column("record_id", sa.Integer, sa.ForeignKey("records.id"), nullable=False),
             sa.Column("path", sa.Text, nullable=False), sa.Column("sha256", sa.String(64), nullable=False),
             sa.Column("size", sa.BigInteger, nullable=False))
    return md


def _v3_columns() -> list[Any]:
    """The columns version 3 adds to ``records``."""
    import sqlalchemy as sa

    return [sa.Column("model_hash", sa.String(64)),
            sa.Column("model_changed", sa.Boolean, nullable=False, server_default=sa.false())]


def _v1(conn) -> None:
    """Version 1: robots, records, parameters, inputs."""
    _tables(1).create_all(conn, tables=[t for n, t in _tables(1).tables.items() if n != "schema_version"])


def _v2(conn) -> None:
    """Version 2: indexes for a robot's records in time order and a record's rows."""
    import sqlalchemy as sa

    t = _tables(2).tables
    sa.Index("records_robot_time", t["records"].c.robot_id, t["records"].c.time, t["records"].c.id).create(conn)
    sa.Index("parameters_record", t["parameters"].c.record_id).create(conn)
    sa.Index("inputs_record", t["inputs"].c.record_id).create(conn)


def _v3(conn) -> None:
    """Version 3: each record's model hash and the flag of a changed nominal model, filled in for the records
    kept so far from their payloads (in time order per robot)."""
    import sqlalchemy as sa
    from sqlalchemy.schema import CreateColumn

    added = sa.Table("records", sa.MetaData(), *_v3_columns())  # the columns alone, for their DDL
    for column in added.columns:  # the one statement both databases share, the column as each spells it
        conn.execute(sa.text(f"ALTER TABLE records ADD COLUMN {CreateColumn(column).compile(dialect=conn.dialect)}"))
    tables = _tables(3).tables
    records, robots = tables["records"], tables["robots"]
    last: dict[int, str] = {}
    rows = conn.execute(sa.select(records.c.id, records.c.robot_id, records.c.payload)
                        .order_by(records.c.robot_id, records.c.time, records.c.id)).all()
    for rid, robot, payload in rows:
        found = str(((payload or {}).get("identity") or {}).get("model_hash") or "") or None
        changed = bool(found and last.get(robot) and found != last[robot])
        last[robot] = found or last.get(robot, "")
        conn.execute(records.update().where(records.c.id == rid).values(model_hash=found, model_changed=changed))
    for robot, found in last.items():  # the robot's model: its latest record's, as version 3 keeps it
        if found:
            conn.execute(robots.update().where(robots.c.id == robot).values(model_hash=found))


MIGRATIONS: tuple[Callable[[Any], None], ...] = (_v1, _v2, _v3)  # step k brings a store to version k + 1


def _sqlite_engine(path: Path, reading: str = ""):
    """An SQLite engine on ``path``: WAL journal, foreign keys, a busy timeout, and SQLAlchemy's recipe for
    pysqlite's transactions (its own BEGIN off; ours: IMMEDIATE for writes, so a writer waits for the lock at
    the start instead of failing later). ``reading``: the SQLite URI parameter of a store that can only be read
    (:func:`_read_only`), its journal mode left as it is."""
    import sqlalchemy as sa

    if reading:  # a URI: the file opened read-only (or immutable), through pysqlite's uri=True
        engine = sa.create_engine("sqlite://", creator=lambda: sqlite3.connect(
            f"file:{quote(str(path.resolve()))}?{reading}", uri=True, timeout=BUSY_TIMEOUT_S,
            check_same_thread=False), json_serializer=_dumps)
    else:
        engine = sa.create_engine(f"sqlite:///{path}", connect_args={"timeout": BUSY_TIMEOUT_S},
                                  json_serializer=_dumps)

    @sa.event.listens_for(engine, "connect")
    def connect(dbapi_connection, record) -> None:
        dbapi_connection.isolation_level = None
        cursor = dbapi_connection.cursor()
        cursor.execute(f"PRAGMA busy_timeout = {int(BUSY_TIMEOUT_S * 1000)}")
        if not reading:  # setting the journal mode writes the file
            cursor.execute("PRAGMA journal_mode = WAL")
            cursor.execute("PRAGMA synchronous = NORMAL")  # WAL: a commit survives its process being killed
        cursor.execute("PRAGMA foreign_keys = ON")
        cursor.close()

    @sa.event.listens_for(engine, "begin")
    def begin(conn) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE" if conn.get_execution_options().get("write") else "BEGIN")
    return engine


def _dumps(obj: Any) -> str:
    return json.dumps(obj, allow_nan=False)


def _engine(url: str) -> tuple[Any, str]:
    """The engine of a store ``url`` (a path or sqlite:///path, its folder must exist, or postgresql://…) and why
    it can only be read ('' when it can be written: :func:`_read_only`)."""
    import sqlalchemy as sa

    if url.startswith(("postgresql:", "postgresql+psycopg:", "postgres:")):
        if importlib.util.find_spec("psycopg") is None:
            raise StoreError(f"the store {_shown(url)} is a PostgreSQL server, and its driver psycopg is not "
                             f"installed: {POSTGRES_HINT}")
        real = "postgresql+psycopg:" + url.split(":", 1)[1]
        return sa.create_engine(real, json_serializer=_dumps), ""
    if "://" in url and not url.startswith("sqlite:///"):
        raise StoreError(f"store '{_shown(url)}': give a file path or sqlite:///PATH (SQLite), or "
                         f"postgresql://USER@HOST/DATABASE (a PostgreSQL server)")
    path = Path(url.removeprefix("sqlite:///")).expanduser()
    if not path.parent.is_dir():
        raise StoreError(f"store {path}: the folder {path.parent} does not exist; create it or give another path")
    if path.is_dir():
        raise StoreError(f"store {path}: is a folder; give the store's file, e.g. {path / 'kincal.db'}")
    why, reading = _read_only(path)
    return _sqlite_engine(path, reading), why


def _read_only(path: Path) -> tuple[str, str]:
    """Why the SQLite store ``path`` can only be read ('' when it can be written) and the SQLite URI parameter
    to read it by: ``mode=ro``, or ``immutable=1`` when its folder is not writable and no write-ahead log is
    beside it (SQLite cannot create the shared-memory file a WAL store's readers need; the file is then all
    there is to read). A StoreError when the store does not exist and its folder is not writable."""
    folder = os.access(path.parent, os.W_OK)
    if folder and (not path.exists() or os.access(path, os.W_OK)):
        return "", ""
    if not path.exists():
        raise StoreError(f"store {path}: the folder {path.parent} is not writable, so the store cannot be created "
                         f"there; give a path in a writable folder")
    why = f"the file {path} is not writable" if folder else f"the folder {path.parent} is not writable"
    wal = path.with_name(path.name + "-wal").exists()
    return why, "mode=ro" if folder or wal else "immutable=1"


def _shown(url: str) -> str:
    """The URL without its password."""
    import sqlalchemy as sa

    try:
        return sa.make_url(url).render_as_string(hide_password=True)
    except Exception:  # not a URL: a path
        return url


def open_store(url: str) -> "Store":
    """Open the calibration store at ``url``, migrated to this kincal's schema.

    Parameters
    ----------
    url : str
        A file path or sqlite:///PATH (an SQLite file, created when missing; its folder must exist; opened
        read-only when it or its folder is not writable), or postgresql://USER@HOST/DATABASE (a server's
        database; needs the psycopg driver).

    Returns
    -------
    Store
        The open store (a context manager that closes it).

    Raises
    ------
    StoreError
        Saying why it cannot be opened: a missing folder, a folder given for the file, an unknown URL
        scheme, no driver, a schema newer than this kincal's, or the database's own error.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from kincal.history import Identity, event_record, open_store
    >>> arm = Identity("cell-3 arm", "SN42")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     with open_store(str(Path(folder) / "robots.db")) as store:
    ...         rid = store.add(event_record(arm, "gearbox of joint 3 replaced", "2024-05-03T12:00Z"))
    ...         kept = store.records("cell-3 arm")
    ...         version = store.version
    >>> rid, version, [(i, r.kind, r.time, r.note) for i, r in kept]
    (1, 3, [(1, 'event', '2024-05-03T12:00:00.000000Z', 'gearbox of joint 3 replaced')])
    >>> open_store("/no/such/folder/robots.db")
    Traceback (most recent call last):
        ...
    kincal.history.store.StoreError: store /no/such/folder/robots.db: the folder /no/such/folder does not exist; ...
    """
    engine, why = _engine(url)
    return Store(engine, url, why)


def migrate(engine, upto: int = SCHEMA_VERSION) -> int:
    """Bring a store to schema ``upto`` in one write transaction (nothing when it is there already).

    The steps of :data:`MIGRATIONS` from the store's version to ``upto`` are applied in order, under the
    writers' lock (another process may have migrated it meanwhile). :func:`open_store` migrates every
    store it opens.

    Parameters
    ----------
    engine : sqlalchemy.engine.Engine
        The store's engine (:attr:`Store.engine`).
    upto : int, optional
        The schema version wanted (default :data:`SCHEMA_VERSION`, this kincal's).

    Returns
    -------
    int
        The version the store has now.

    Raises
    ------
    StoreError
        When the store's schema is newer than this kincal's.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from kincal.history import SCHEMA_VERSION, migrate, open_store
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     with open_store(str(Path(folder) / "robots.db")) as store:
    ...         now = migrate(store.engine)  # opened at this kincal's version: nothing to do
    >>> now == SCHEMA_VERSION
    True
    """
    import sqlalchemy as sa

    def version(conn) -> int:
        if not sa.inspect(conn).has_table("schema_version"):
            return 0
        found = conn.execute(sa.select(_tables(1).tables["schema_version"].c.version)).scalar()
        return int(found or 0)

    with engine.connect() as conn, conn.begin():
        now = version(conn)
    if now > SCHEMA_VERSION:
        raise StoreError(f"the store {_shown(str(engine.url))} has schema version {now}, newer than this kincal's "
                         f"({SCHEMA_VERSION}): upgrade kincal (pip install -U kincal) to read it")
    if now >= upto:
        return now
    with write(engine) as conn:
        now = version(conn)  # again, under the lock: another process may have migrated it meanwhile
        table = _tables(1).tables["schema_version"]
        table.create(conn, checkfirst=True)
        for step in MIGRATIONS[now:upto]:
            step(conn)
        conn.execute(table.delete())
        conn.execute(table.insert().values(version=max(now, upto)))
    return max(now, upto)


@contextmanager
def write(engine) -> Iterator[Any]:
    """A write transaction on ``engine`` (yields the connection): SQLite's BEGIN IMMEDIATE, PostgreSQL's advisory
    lock; committed when the block ends, rolled back on an error."""
    import sqlalchemy as sa

    with engine.connect() as conn:
        conn = conn.execution_options(write=True)
        with conn.begin():
            if conn.dialect.name == "postgresql":
                conn.execute(sa.select(sa.func.pg_advisory_xact_lock(LOCK_KEY)))
            yield conn


def as_record(payload: Any, rid: int) -> Record:
    """A record from its stored payload; a StoreError names the record when it is not one."""
    try:
        return Record.from_dict(payload)
    except (KeyError, TypeError, ValueError) as exc:
        raise StoreError(f"store record {rid} cannot be read ({exc}); was it edited by hand?") from None


class Store:
    """A calibration store: every record of every robot in one database; a context manager that closes it.

    Open one with :func:`open_store`. Every write is one transaction; reads return records in time
    order.

    Parameters
    ----------
    engine : sqlalchemy.engine.Engine
        The database's engine (SQLite or PostgreSQL); the store is migrated to this kincal's schema.
    url : str
        The store's path or URL, as given (shown in messages without its password).
    read_only : str, optional
        Why the store can only be read (its folder or file is not writable), '' (default) when it can be written:
        :meth:`add` is then refused, saying so.

    Attributes
    ----------
    engine : sqlalchemy.engine.Engine
        The database's engine.
    url : str
        The store's path or URL.
    version : int
        The schema version of the store (:data:`SCHEMA_VERSION` once opened).

    Raises
    ------
    StoreError
        When the database cannot be opened or migrated.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from kincal.history import Identity, Record, event_record, open_store
    >>> arm = Identity("cell-3 arm", "SN42")
    >>> calibrated = Record(arm, "calibration", "2024-05-01T08:00Z", "good", parameters={"j2.theta": 1e-3})
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     with open_store(str(Path(folder) / "robots.db")) as store:
    ...         first = store.add(calibrated)
    ...         second = store.add(event_record(arm, "crash at 40 % speed", "2024-05-03T12:00Z"))
    ...         robots = store.robots()
    ...         back = store.get(first)
    ...         events = store.records("cell-3 arm", kind="event")
    >>> robots
    [(Identity(name='cell-3 arm', serial='SN42', model_hash=''), 2, '2024-05-01T08:00:00.000000Z',
      '2024-05-03T12:00:00.000000Z')]
    >>> back == calibrated, [i for i, _ in events]
    (True, [2])
    """

    def __init__(self, engine, url: str, read_only: str = "") -> None:
        import sqlalchemy as sa

        self.engine, self.url, self.read_only = engine, url, read_only
        self.tables = _tables(SCHEMA_VERSION).tables
        try:
            self.version = migrate(engine)
        except sa.exc.SQLAlchemyError as exc:
            engine.dispose()
            raise StoreError(f"the store {_shown(url)} cannot be opened: {_reason(exc)}" + (
                f" ({read_only}: it can only be read, and its schema needs bringing up to date by a kincal that "
                f"can write it)" if read_only else "")) from None

    def __enter__(self) -> "Store":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Close the store's connections."""
        self.engine.dispose()

    def add(self, record: Record) -> int:
        """Record ``record`` (one transaction: the robot's row, the record, its parameter and input rows); its id.

        An evaluation or check of a calibrated robot file (its payload's ``evaluated`` fingerprint) is linked to
        the calibration record that wrote that file (``evaluated["record"]``, by the file's sha256). A StoreError,
        nothing recorded, when the store can only be read (:attr:`read_only`), the record is dated in the future
        (:func:`kincal.history.not_in_future`), says what one of the robot's records says already
        (:meth:`Record.same_as`: the same session recorded twice), or is dated before the calibration it
        evaluates."""
        if self.read_only:
            raise StoreError(f"nothing recorded: the calibration store {_shown(self.url)} can only be read "
                             f"({self.read_only}); record into a store in a writable folder, or make it writable")
        try:
            not_in_future(record.time)
        except ValueError as exc:
            raise StoreError(f"nothing recorded: {exc}") from None
        t, ident = self.tables, record.identity
        with write(self.engine) as conn:
            robot = conn.execute(t["robots"].select().where(t["robots"].c.name == ident.name,
                                                            t["robots"].c.serial == ident.serial)).first()
            record = record if robot is None else self._checked(conn, robot.id, record)
            changed = bool(robot is not None and ident.model_hash and robot.model_hash
                           and ident.model_hash != robot.model_hash)
            if robot is None:
                robot_id = conn.execute(t["robots"].insert().values(
                    name=ident.name, serial=ident.serial, model_hash=ident.model_hash)).inserted_primary_key[0]
            else:
                robot_id = robot.id
                if ident.model_hash and ident.model_hash != robot.model_hash:
                    conn.execute(t["robots"].update().where(t["robots"].c.id == robot_id)
                                 .values(model_hash=ident.model_hash))
            rid = conn.execute(t["records"].insert().values(
                robot_id=robot_id, kind=record.kind, time=record.time, verdict=record.verdict, note=record.note,
                payload=record.to_dict(), model_hash=ident.model_hash or None,
                model_changed=changed)).inserted_primary_key[0]
            known = set(record.identifiable)
            rows = [{"record_id": rid, "name": n, "value": v, "sigma": record.sigmas.get(n), "identifiable": n in known}
                    for n, v in record.parameters.items()]
            if rows:
                conn.execute(t["parameters"].insert(), rows)
            if record.inputs:
                conn.execute(t["inputs"].insert(), [{"record_id": rid, **i.to_dict()} for i in record.inputs])
        return int(rid)

    def _checked(self, conn, robot_id: int, record: Record) -> Record:
        """``record`` for the robot ``robot_id``, checked against its records (:meth:`add`) and linked to the
        calibration it evaluates; a StoreError naming the record it repeats."""
        rec = self.tables["records"]
        for rid, payload in conn.execute(rec.select().with_only_columns(rec.c.id, rec.c.payload).where(
                rec.c.robot_id == robot_id, rec.c.kind == record.kind, rec.c.time == record.time,
                rec.c.note == record.note)).all():
            if as_record(payload, rid).same_as(record):
                raise StoreError(f"nothing recorded: the same {record.kind} is record {rid} of the store "
                                 f"{_shown(self.url)} (dated {record.time[:16].replace('T', ' ')} UTC, the same "
                                 f"input files by their sha256, the same results): it was recorded already")
        evaluated = record.payload.get("evaluated")
        if not isinstance(evaluated, dict) or not evaluated.get("sha256"):
            return record
        made = [(rid, when) for rid, when, payload in conn.execute(
            rec.select().with_only_columns(rec.c.id, rec.c.time, rec.c.payload).where(
                rec.c.robot_id == robot_id, rec.c.kind == "calibration").order_by(rec.c.time, rec.c.id)).all()
                if ((payload.get("payload") or {}).get("output") or {}).get("sha256") == evaluated["sha256"]]
        if not made:
            return record
        rid = made[-1][0]  # (its data may be older than the calibration: poses held out from the same session)
        return dataclasses.replace(record, payload={**record.payload, "evaluated": {**evaluated, "record": rid}})

    def _read(self, query) -> list:
        with self.engine.connect() as conn, conn.begin():
            return list(conn.execute(query).all())

    def records(self, name: str, serial: str | None = None, kind: str | None = None) -> list[tuple[int, Record]]:
        """(id, record) of the robot ``name`` (of one ``serial``, else every serial), of one ``kind`` or all,
        ordered by (time, id)."""
        t = self.tables
        rec, rob = t["records"], t["robots"]
        query = rec.select().join(rob, rec.c.robot_id == rob.c.id).where(rob.c.name == name)
        query = query.where(rob.c.serial == serial) if serial is not None else query
        query = query.where(rec.c.kind == kind) if kind is not None else query
        return [(int(r.id), as_record(r.payload, r.id)) for r in self._read(query.order_by(rec.c.time, rec.c.id))]

    def model_changes(self, name: str, serial: str | None = None) -> set[int]:
        """Ids of the robot's records whose nominal model differs from the one recorded before them."""
        t = self.tables
        rec, rob = t["records"], t["robots"]
        query = (rec.select().with_only_columns(rec.c.id).join(rob, rec.c.robot_id == rob.c.id)
                 .where(rob.c.name == name, rec.c.model_changed))
        query = query.where(rob.c.serial == serial) if serial is not None else query
        return {int(r.id) for r in self._read(query)}

    def robots(self) -> list[tuple[Identity, int, str | None, str | None]]:
        """Every robot: (identity with the latest model hash, number of records, first and last record's time),
        ordered by name and serial."""
        import sqlalchemy as sa

        rec, rob = self.tables["records"], self.tables["robots"]
        query = (sa.select(rob.c.name, rob.c.serial, rob.c.model_hash, sa.func.count(rec.c.id),
                           sa.func.min(rec.c.time), sa.func.max(rec.c.time))
                 .select_from(rob.outerjoin(rec, rec.c.robot_id == rob.c.id))
                 .group_by(rob.c.id, rob.c.name, rob.c.serial, rob.c.model_hash).order_by(rob.c.name, rob.c.serial))
        return [(Identity(r[0], r[1], r[2]), int(r[3]), r[4], r[5]) for r in self._read(query)]

    def get(self, rid: int) -> Record:
        """The record ``rid``; a StoreError when the store has none."""
        rec = self.tables["records"]
        rows = self._read(rec.select().where(rec.c.id == int(rid)))
        if not rows:
            raise StoreError(f"the store {_shown(self.url)} has no record {rid}")
        return as_record(rows[0].payload, rid)


def _reason(exc: Exception) -> str:
    """A database error's own message, first line (SQLAlchemy's wrapper text and links left out)."""
    inner = exc.orig if isinstance(exc, sa_errors().DBAPIError) and exc.orig is not None else exc
    return str(inner).strip().splitlines()[0] if str(inner).strip() else type(inner).__name__


def sa_errors():
    import sqlalchemy.exc

    return sqlalchemy.exc
