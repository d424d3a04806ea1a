"""The swatch library: every capture, estimate (and dye prediction) a lab made, searchable by colour.

One embedded SQLite file in the user's data folder (WAL mode; ``~/.local/share/hairdigi/library.sqlite``),
or one PostgreSQL database shared by several benches, with the same schema and the same SQL.
``HAIRDIGI_LIBRARY`` (a file path, a ``postgresql://`` URL or a libpq keyword string, read by one
function, :func:`parse_location`) overrides the default; no password is ever shown (:func:`redact`). The schema
evolves by numbered migrations (``MIGRATIONS``), each applied once, in a transaction.

Every write is one transaction: a session's import is all there or not there, whatever kills the
process; two processes writing at once queue (SQLite: ``BEGIN IMMEDIATE`` and a busy timeout;
PostgreSQL: its own locking). Qt-free: the window's Library panel only shows this.
"""
from __future__ import annotations

import json
import logging
import os
import re
import sqlite3
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator
from urllib.parse import parse_qsl, unquote

import numpy as np

from hairdigi.app.library.swatch_colour import COLOURS, delta_e
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.params import HairParams, HairParamsError
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import CaptureRecord, EstimateRecord, capture_profile

KINDS = ("capture", "estimate", "dye")   # dye: predictions of issue "Hair-dye development", same layout
BUSY_TIMEOUT_S = 5.0            # SQLite: the longest wait for another writer's lock
CONNECT_TIMEOUT_S = 5           # PostgreSQL: per host, to connect and be answered
LOCK_TIMEOUT_S = 5.0            # PostgreSQL: the longest wait for a lock (advisory locks included)
STATEMENT_TIMEOUT_S = 60.0      # PostgreSQL: the longest statement
#: CIEDE2000's lightness weight S_L = 1 + 0.015 (L - 50)^2 / sqrt(20 + (L - 50)^2) is at most this on 0-100.
SL_MAX = 1.0 + 0.015 * 2500 / (20 + 2500) ** 0.5 + 1e-6
FIRST_BAND = 4.0     # L* either side of the query read first


class LibraryError(HairdigiError, ValueError):
    """The library cannot be opened or does not hold what was asked; the message says which."""


def default_location() -> Path:
    """``$XDG_DATA_HOME/hairdigi/library.sqlite`` (``~/.local/share/hairdigi/library.sqlite``)."""
    base = os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share"
    return Path(base) / "hairdigi" / "library.sqlite"


def location() -> str:
    """Where the library is: ``HAIRDIGI_LIBRARY`` (a file path, a PostgreSQL URL or a libpq keyword string,
    read by :func:`parse_location`), else the default file."""
    return (os.environ.get("HAIRDIGI_LIBRARY") or "").strip() or str(default_location())


# --- addresses: parsed once, shown without their password -------------------------------------------
#: libpq's connection settings (``PQconndefaults``): a keyword string names only these.
LIBPQ_KEYWORDS = frozenset((
    "host", "hostaddr", "port", "dbname", "user", "password", "passfile", "require_auth", "channel_binding",
    "connect_timeout", "client_encoding", "options", "application_name", "fallback_application_name", "keepalives",
    "keepalives_idle", "keepalives_interval", "keepalives_count", "tcp_user_timeout", "replication", "gssencmode",
    "sslmode", "sslnegotiation", "requiressl", "sslcompression", "sslcert", "sslkey", "sslkeylogfile", "sslpassword",
    "sslcertmode", "sslrootcert", "sslcrl", "sslcrldir", "sslsni", "requirepeer", "ssl_min_protocol_version",
    "ssl_max_protocol_version", "krbsrvname", "gsslib", "gssdelegation", "service", "target_session_attrs",
    "load_balance_hosts", "min_protocol_version", "max_protocol_version", "scram_client_key", "scram_server_key",
    "oauth_issuer", "oauth_client_id", "oauth_client_secret", "oauth_scope"))
#: Settings whose value is a secret, never shown.
SECRET_KEYS = ("password", "sslpassword", "oauth_client_secret")
FORMS = ("a PostgreSQL URL (postgresql://user@host/db), a libpq keyword string (host=... dbname=...) or the path "
         "of a SQLite file")
_SCHEME = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*):")
_POSTGRES_SCHEME = re.compile(r"(?i)^postgres(?:ql)?(?:\+[a-z0-9_]+)?$")
_KEY = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)\s*=\s*")
_SECRET = "|".join(SECRET_KEYS)
#: A URL's ``user:PASSWORD@`` (to the last ``@``: a password may hold one), its query's ``password=``, and a
#: keyword string's ``password=VALUE`` (quoted, unterminated, or unquoted up to the next ``key=``).
_URL_PASSWORD = re.compile(r"(?i)\b([a-z][a-z0-9+.-]*:/+[^:/@\s]*):.*@")
_QUERY_PASSWORD = re.compile(rf"(?i)([?&](?:{_SECRET})=)[^&#\s]*")
_KEYWORD_PASSWORD = re.compile(rf"(?i)(?<![?&\w])((?:{_SECRET})\s*=\s*)"
                               r"('(?:[^'\\]|\\.)*'?|\S*(?:\s+(?![A-Za-z_][A-Za-z0-9_]*\s*=)\S+)*)")


@dataclass(frozen=True)
class Address:
    """A library's address, parsed once (:func:`parse_location`): a SQLite file's ``path``, or the
    ``conninfo`` a PostgreSQL driver connects to; ``secrets``, its password in every form and part, are
    masked wherever a message shows text."""

    given: str
    path: Path | None = None
    conninfo: str | None = None
    secrets: tuple[str, ...] = ()

    @property
    def postgres(self) -> bool:
        return self.conninfo is not None

    @property
    def shown(self) -> str:
        return _mask(self.given, self.secrets)


def parse_location(where: str | os.PathLike) -> Address:
    """The one reading of a library address: a URL (any scheme case; ``postgres://``,
    ``postgresql+driver://``), a libpq keyword string (``host=... password='...'``) or a file path. An
    address that is none of these, or that the driver would misread, raises :class:`LibraryError` naming
    the fix (without its password)."""
    text = os.fspath(where).strip()
    scheme = _SCHEME.match(text)
    if scheme and (text[scheme.end():].startswith("//") or _POSTGRES_SCHEME.match(scheme.group(1))):
        return _url_address(text, scheme.group(1))
    key = _KEY.match(text)
    if key and key.group(1).lower() in LIBPQ_KEYWORDS:
        return _keyword_address(text)
    return Address(text, path=Path(text).expanduser())


def _secret_parts(*values: str) -> tuple[str, ...]:
    """A password's every form: whole, URL-decoded, and each run of 3 or more letters and digits in it."""
    forms = {v for value in values if value for v in (value, unquote(value))}
    parts = {p for v in forms for p in re.split(r"[^0-9A-Za-z]+", v) if len(p) >= 3}
    return tuple(sorted(forms | parts, key=len, reverse=True))


def _url_address(text: str, scheme: str) -> Address:
    """A ``scheme://`` address: PostgreSQL's (normalised to ``postgresql://``), else refused."""
    if not _POSTGRES_SCHEME.match(scheme):
        raise LibraryError(f"HAIRDIGI_LIBRARY {_mask(text)}: a {scheme.lower()}:// address, which hairdigi cannot "
                           f"open; give {FORMS}")
    rest = text[len(scheme) + 1:]
    if not rest.startswith("//"):
        raise LibraryError(f"HAIRDIGI_LIBRARY holds a {scheme.lower()}: address without its '//'; write it as "
                           f"postgresql://user@host/db")
    body = rest[2:]
    userinfo = body[:body.rfind("@")] if "@" in body else ""
    password = userinfo.partition(":")[2] if ":" in userinfo else ""
    query = body.partition("?")[2]
    secrets = [password] + [v for k, v in parse_qsl(query, keep_blank_values=True) if k.lower() in SECRET_KEYS]
    if re.search(r"[@/?#\s]", password):
        raise LibraryError(f"HAIRDIGI_LIBRARY {_mask(text)}: the password holds '@', '/', '?', '#' or a space, "
                           f"which a URL must percent-encode (%40, %2F, %3F, %23, %20); encode them, or give a "
                           f"keyword string: host=... user=... password='...'")
    return Address(text, conninfo="postgresql://" + body, secrets=_secret_parts(*secrets))


def _keyword_address(text: str) -> Address:
    """A libpq keyword string, read by libpq's rules (``key = value``, a value quoted with ``'`` and ``\\``
    escapes where it holds a space); a word that is not ``key=value`` or a setting libpq does not know is
    refused without showing it where it may be part of a password."""
    pairs, pos, after_secret = [], 0, False
    while True:
        while pos < len(text) and text[pos].isspace():
            pos += 1
        if pos >= len(text):
            break
        key = _KEY.match(text, pos)
        if not key:
            raise LibraryError("HAIRDIGI_LIBRARY: the keyword string holds a word that is not key=value (a password "
                               "with a space must be quoted: password='two words'); check its quoting")
        name, pos = key.group(1).lower(), key.end()
        if name not in LIBPQ_KEYWORDS:
            shown = "a setting" if after_secret else repr(name[:40])
            raise LibraryError(f"HAIRDIGI_LIBRARY: the keyword string names {shown} that libpq does not know; "
                               f"use host, port, dbname, user, password, sslmode... (a password with a space must "
                               f"be quoted: password='two words')")
        value, pos, quoted = _keyword_value(text, pos)
        pairs.append((name, value))
        after_secret = name in SECRET_KEYS and not quoted
    if not any(k in ("host", "hostaddr", "dbname", "service", "port", "user") for k, _ in pairs):
        raise LibraryError(f"HAIRDIGI_LIBRARY {_mask(text)}: the keyword string names no server or database; "
                           f"give {FORMS}")
    return Address(text, conninfo=text, secrets=_secret_parts(*(v for k, v in pairs if k in SECRET_KEYS)))


def _keyword_value(text: str, pos: int) -> tuple[str, int, bool]:
    """The value at ``pos`` of a keyword string, the position after it, and whether it was quoted."""
    out, quoted = [], pos < len(text) and text[pos] == "'"
    pos += quoted
    while pos < len(text):
        c = text[pos]
        if quoted and c == "'":
            return "".join(out), pos + 1, True
        if not quoted and c.isspace():
            break
        if c == "\\" and pos + 1 < len(text):
            pos += 1
            c = text[pos]
        out.append(c)
        pos += 1
    if quoted:
        raise LibraryError("HAIRDIGI_LIBRARY: a quoted value of the keyword string is not closed (a ' is missing); "
                           "close it: password='two words'")
    return "".join(out), pos, False


def redact(text: str | os.PathLike) -> str:
    """An address (or a message about one) with every password masked as ``***``, whole and in part: what
    :func:`parse_location` finds its password to be, wherever it appears, and by its form: a URL's
    ``user:PASSWORD@`` (to its last ``@``), a URL's ``?password=``, a keyword string's ``password=`` (quoted,
    unclosed, or up to the next ``key=``), and ``sslpassword`` alike."""
    text = os.fspath(text)
    try:
        secrets = parse_location(text).secrets
    except LibraryError:
        secrets = ()
    return _mask(text, secrets)


def _mask(text: str, secrets: tuple[str, ...] = ()) -> str:
    """``text`` with each of ``secrets`` and every password found by its form masked."""
    for secret in secrets:
        text = text.replace(secret, "***")
    text = _URL_PASSWORD.sub(r"\1:***@", text)
    text = _QUERY_PASSWORD.sub(r"\1***", text)
    return _KEYWORD_PASSWORD.sub(r"\1***", text)


def driver_message(exc: BaseException, address: Address) -> str:
    """A driver's message on one line, with the address's password masked wherever it appears, whole or in part."""
    return _mask(" ".join(str(exc).split()) or type(exc).__name__, address.secrets)[:400]


def is_url(where: str) -> bool:
    """Whether ``where`` addresses a PostgreSQL server (a URL or a keyword string), not a file."""
    return parse_location(where).postgres


# --- schema ----------------------------------------------------------------------------------------
#: Numbered migrations; a database at version N gets N+1... applied in order. Portable SQL only.
MIGRATIONS: tuple[tuple[int, str, tuple[str, ...]], ...] = (
    (1, "swatches, their colours, imported sessions", (
        """CREATE TABLE swatches (
            id TEXT PRIMARY KEY,
            kind TEXT NOT NULL,
            session TEXT,
            capture_id TEXT,
            captured TEXT,
            imported TEXT NOT NULL,
            image_path TEXT,
            record_path TEXT,
            record_sha256 TEXT,
            reliable INTEGER NOT NULL DEFAULT 0,
            hair TEXT,
            sigma_r DOUBLE PRECISION, sigma_g DOUBLE PRECISION, sigma_b DOUBLE PRECISION,
            record TEXT NOT NULL,
            note TEXT NOT NULL DEFAULT '')""",
        """CREATE TABLE colours (
            swatch_id TEXT NOT NULL REFERENCES swatches(id) ON DELETE CASCADE,
            illuminant TEXT NOT NULL,
            l DOUBLE PRECISION NOT NULL, a DOUBLE PRECISION NOT NULL, b DOUBLE PRECISION NOT NULL,
            PRIMARY KEY (swatch_id, illuminant))""",
        "CREATE INDEX colours_by_illuminant ON colours (illuminant, l)",
        "CREATE TABLE sessions (path TEXT PRIMARY KEY, imported TEXT NOT NULL, captures INTEGER NOT NULL)",
    )),
    (2, "tags and library settings", (
        """CREATE TABLE tags (
            swatch_id TEXT NOT NULL REFERENCES swatches(id) ON DELETE CASCADE,
            tag TEXT NOT NULL,
            PRIMARY KEY (swatch_id, tag))""",
        "CREATE INDEX tags_by_tag ON tags (tag)",
        "CREATE TABLE settings (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
    )),
    (3, "the lab's own instrument readings of its tresses", (
        """CREATE TABLE readings (
            tress TEXT NOT NULL,
            geometry TEXT NOT NULL,
            observer TEXT NOT NULL,
            illuminant TEXT NOT NULL,
            l DOUBLE PRECISION NOT NULL, a DOUBLE PRECISION NOT NULL, b DOUBLE PRECISION NOT NULL,
            source TEXT NOT NULL,
            line INTEGER NOT NULL,
            imported TEXT NOT NULL,
            PRIMARY KEY (source, line, geometry))""",
        "CREATE INDEX readings_by_tress ON readings (tress)",
    )),
)
SCHEMA_VERSION = MIGRATIONS[-1][0]


@dataclass(frozen=True)
class SwatchRecord:
    """What a swatch's ``record`` column holds, typed: a capture's records (its capture record and its
    result, an estimate record or None where none was written), or a lone estimate record (a dye
    prediction is one too); neither for a row written without records.

    ``to_json()`` is the column's JSON as it has always been written: ``{"capture": ..., "result": ...}``
    for a capture, the estimate record itself for a lone one, ``{}`` for neither. :meth:`from_json` reads
    it back through the records' own readers (``CaptureRecord.from_json``, ``EstimateRecord.from_json``),
    which upgrade older layouts."""

    capture: CaptureRecord | None = None
    estimate: EstimateRecord | None = None     # a capture's result, or the lone estimate

    def to_json(self) -> dict:
        if self.capture is not None:
            return {"capture": self.capture.to_json(),
                    "result": None if self.estimate is None else self.estimate.to_json()}
        return {} if self.estimate is None else self.estimate.to_json()

    @classmethod
    def from_json(cls, data: dict) -> "SwatchRecord":
        """A ``record`` column's JSON, read back; :class:`RecordError` names what is wrong with it."""
        if not isinstance(data, dict):
            raise RecordError(f"a swatch's record is a JSON object, not {type(data).__name__}")
        if not data:
            return cls()
        if isinstance(data.get("capture"), dict):     # an estimate's own "capture" is its image's name
            result = data.get("result")
            # a first-layout still kept its calibration profile in its result record
            legacy = capture_profile(None, result if isinstance(result, dict) else None)
            return cls(capture=CaptureRecord.from_json(data["capture"], legacy_profile=legacy),
                       estimate=None if result is None else EstimateRecord.from_json(result))
        return cls(estimate=EstimateRecord.from_json(data))


@dataclass
class SwatchRow:
    """One swatch as written: its identity, where it came from, its records and colours. ``hair``,
    ``sigma_a`` and ``reliable`` are the columns the library searches and shows without reading the record."""

    id: str
    kind: str
    record: SwatchRecord = field(default_factory=SwatchRecord)
    session: str | None = None
    capture_id: str | None = None
    captured: str | None = None
    image_path: str | None = None
    record_path: str | None = None
    record_sha256: str | None = None
    reliable: bool = False
    hair: HairParams | None = None
    sigma_a: tuple[float, float, float] | None = None
    labs: dict[str, tuple[float, float, float]] = field(default_factory=dict)   # illuminant -> CIELAB


@dataclass
class Swatch:
    """One swatch as read back, with its tags and note."""

    id: str
    kind: str
    session: str | None
    capture_id: str | None
    captured: str | None
    imported: str
    image_path: str | None
    record_path: str | None
    reliable: bool
    hair: HairParams | None            # Table 1 parameters; None: no estimate (blocked)
    sigma_a: tuple[float, float, float] | None
    note: str
    tags: tuple[str, ...] = ()
    labs: dict[str, tuple[float, float, float]] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.capture_id or Path(self.record_path or self.id).name


# --- connections -----------------------------------------------------------------------------------
class _Db:
    """One connection, SQLite or PostgreSQL, behind the same few calls (SQL written with ``?``).

    Every wait is bounded: SQLite waits ``BUSY_TIMEOUT_S`` for another writer's lock; PostgreSQL
    ``CONNECT_TIMEOUT_S`` per host to connect, ``LOCK_TIMEOUT_S`` for a lock and
    ``STATEMENT_TIMEOUT_S`` for a statement. A wait that runs out is one line naming the lock or the
    server (:class:`LibraryError`), as is a read-only file or another program's database."""

    def __init__(self, where: str) -> None:
        self.where = where
        self.address = parse_location(where)
        self.shown = self.address.shown
        self.postgres = self.address.postgres
        if self.postgres:
            try:
                import psycopg   # deferred: psycopg is the optional [postgres] extra
            except ModuleNotFoundError:
                raise LibraryError("a PostgreSQL library needs psycopg: pip install 'psycopg[binary]'") from None
            options = (f"-c lock_timeout={int(LOCK_TIMEOUT_S * 1000)} "
                       f"-c statement_timeout={int(STATEMENT_TIMEOUT_S * 1000)}")
            try:
                self.conn = psycopg.connect(self.address.conninfo, autocommit=True, connect_timeout=CONNECT_TIMEOUT_S,
                                            options=options)
            except psycopg.Error as exc:
                raise LibraryError(f"cannot connect to the library at {self.shown} within {CONNECT_TIMEOUT_S} s a "
                                   f"host: {driver_message(exc, self.address)}; check that the server runs and "
                                   f"answers, or set HAIRDIGI_LIBRARY to another library") from None
        else:
            path = self.address.path
            self._check_file(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            try:
                self.conn = sqlite3.connect(path, timeout=BUSY_TIMEOUT_S, isolation_level=None,
                                            check_same_thread=False)
                self.conn.execute(f"PRAGMA busy_timeout={int(BUSY_TIMEOUT_S * 1000)}")
                self._check_ours(path)
                with self.errors():
                    self.conn.execute("PRAGMA journal_mode=WAL")
            except sqlite3.DatabaseError as exc:
                raise LibraryError(f"{path}: not a hairdigi library ({exc})") from None
            self.conn.execute("PRAGMA synchronous=NORMAL")
            self.conn.execute("PRAGMA foreign_keys=ON")

    def _check_file(self, path: Path) -> None:
        """A library file must be a regular file the user can write, in a folder they can write (SQLite
        writes its WAL and shared-memory files beside it)."""
        if path.exists() and not path.is_file():
            raise LibraryError(f"{path}: the library is not a regular file (a folder or device); set "
                               f"HAIRDIGI_LIBRARY to a file")
        folder = path.parent if path.parent.exists() else None
        file_ro = path.exists() and (not os.access(path, os.W_OK) or not path.stat().st_mode & 0o222)
        if file_ro or folder and not os.access(folder, os.W_OK | os.X_OK):
            which = path if file_ro else folder
            raise LibraryError(f"{path}: the library is read-only ({which} is not writable); make it writable "
                               f"(chmod u+w) or set HAIRDIGI_LIBRARY to a copy")

    def _check_ours(self, path: Path) -> None:
        """An existing database with tables but no ``schema_version`` belongs to another program: never changed."""
        with self.errors():
            tables = [r[0] for r in self.conn.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name").fetchall()]
        if tables and "schema_version" not in tables:
            shown = ", ".join(tables[:5]) + (", ..." if len(tables) > 5 else "")
            raise LibraryError(f"{path}: a SQLite database of another program (tables {shown}), not a hairdigi "
                               f"library; it is left unchanged: set HAIRDIGI_LIBRARY to a new file")

    @contextmanager
    def errors(self) -> Iterator[None]:
        """Database errors a user can meet (a lock held too long, a read-only file, a server gone) as one line."""
        try:
            yield
        except sqlite3.OperationalError as exc:
            text = str(exc)
            if "locked" in text or "busy" in text:
                raise LibraryError(f"the library {self.shown} is locked by another process (a write that did not "
                                   f"finish within {BUSY_TIMEOUT_S:g} s); try again when it ends, or find the "
                                   f"process holding {self.shown}") from None
            if "readonly" in text or "read-only" in text:
                raise LibraryError(f"the library {self.shown} is read-only ({text}); make it and its folder "
                                   f"writable, or set HAIRDIGI_LIBRARY to a copy") from None
            raise LibraryError(f"the library {self.shown}: {text}") from None
        except Exception as exc:
            if not self.postgres or not type(exc).__module__.startswith("psycopg"):
                raise
            name = type(exc).__name__
            if name in ("LockNotAvailable", "QueryCanceled"):
                raise LibraryError(f"the library {self.shown}: {'a lock' if name == 'LockNotAvailable' else 'a query'} "
                                   f"waited longer than {LOCK_TIMEOUT_S if name == 'LockNotAvailable' else STATEMENT_TIMEOUT_S:g} "
                                   f"s (another session holds it); try again when it ends") from None
            raise LibraryError(f"the library {self.shown}: {driver_message(exc, self.address)}") from None

    def _sql(self, sql: str) -> str:
        return sql.replace("?", "%s") if self.postgres else sql

    def execute(self, sql: str, params: tuple | list = ()):
        with self.errors():
            return self.conn.execute(self._sql(sql), params)

    def executemany(self, sql: str, rows: list) -> None:
        with self.errors():
            if self.postgres:
                with self.conn.cursor() as cur:
                    cur.executemany(self._sql(sql), rows)
            else:
                self.conn.executemany(sql, rows)

    def query(self, sql: str, params: tuple | list = ()) -> list[tuple]:
        with self.errors():
            return list(self.execute(sql, params).fetchall())

    @contextmanager
    def transaction(self) -> Iterator[None]:
        """One transaction: committed when the block ends, rolled back if it raises."""
        if self.postgres:
            with self.errors(), self.conn.transaction():
                yield
            return
        self.execute("BEGIN IMMEDIATE")   # take the write lock now: two writers queue, never deadlock
        try:
            yield
        except BaseException:
            self.conn.execute("ROLLBACK")
            raise
        self.execute("COMMIT")

    def has_table(self, name: str) -> bool:
        if self.postgres:
            return bool(self.query("SELECT 1 FROM information_schema.tables WHERE table_name = ?", (name,)))
        return bool(self.query("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?", (name,)))

    def close(self) -> None:
        self.conn.close()


_redact = redact


def _first_line(exc: BaseException, where: str) -> str:
    """:func:`driver_message` for an address given as text."""
    try:
        address = parse_location(where)
    except LibraryError:
        address = Address(str(where))
    return driver_message(exc, address)


def like_escape(text: str) -> str:
    """``text`` matched literally by ``LIKE ... ESCAPE '\\'``: its ``%``, ``_`` and ``\\`` escaped."""
    return text.replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_")


def _hair(swatch_id: str, text: str | None) -> HairParams | None:
    """A ``hair`` column's Table 1 parameters (``HairParams.to_dict()``'s JSON, as imported), or None."""
    if text is None:
        return None
    try:
        return HairParams.from_dict(json.loads(text))
    except (ValueError, HairParamsError) as exc:     # json's errors and HairParamsError are ValueErrors
        raise LibraryError(f"swatch {swatch_id}: its stored parameters are not Table 1 parameters ({exc}); import "
                           f"its session or record file again (hairdigi library import)") from None


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


# --- the library -----------------------------------------------------------------------------------
class Library:
    """A library connection: migrate on open, then import, find, tag, note and export."""

    def __init__(self, where: str | os.PathLike | None = None, migrate_to: int = SCHEMA_VERSION) -> None:
        self.where = str(where) if where is not None else location()
        self.db = _Db(self.where)
        self.migrate(migrate_to)

    def close(self) -> None:
        self.db.close()

    def __enter__(self) -> "Library":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- schema -----------------------------------------------------------------------------
    @property
    def version(self) -> int:
        if not self.db.has_table("schema_version"):
            return 0
        rows = self.db.query("SELECT MAX(version) FROM schema_version")
        return int(rows[0][0] or 0)

    def migrate(self, to: int = SCHEMA_VERSION) -> list[int]:
        """Apply the migrations this library lacks, each in its own transaction; the versions applied."""
        applied = []
        if self.db.has_table("schema_version") and self.version >= min(to, SCHEMA_VERSION):
            if self.version > SCHEMA_VERSION:
                raise LibraryError(f"the library at {_redact(self.where)} has schema version {self.version}, newer "
                                   f"than this hairdigi knows ({SCHEMA_VERSION}); update hairdigi")
            return applied   # up to date: no write lock taken, so opening never waits for another writer
        with self.db.transaction():
            if self.db.postgres:
                self.db.execute("SELECT pg_advisory_xact_lock(20020)")   # one migrator at a time
            self.db.execute("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER PRIMARY KEY, "
                            "description TEXT NOT NULL, applied TEXT NOT NULL)")
        current = self.version
        if current > SCHEMA_VERSION:
            raise LibraryError(f"the library at {_redact(self.where)} has schema version {current}, newer than "
                               f"this hairdigi knows ({SCHEMA_VERSION}); update hairdigi")
        for version, description, statements in MIGRATIONS:
            if version > to:
                break
            with self.db.transaction():
                if self.db.postgres:
                    self.db.execute("SELECT pg_advisory_xact_lock(20020)")
                if self.db.query("SELECT 1 FROM schema_version WHERE version = ?", (version,)):
                    continue   # another process applied it first
                for statement in statements:
                    self.db.execute(statement)
                self.db.execute("INSERT INTO schema_version (version, description, applied) VALUES (?, ?, ?)",
                                (version, description, _now()))
                applied.append(version)
        return applied

    # -- writes -----------------------------------------------------------------------------
    def add(self, rows: list[SwatchRow], session: str | None = None) -> int:
        """Write ``rows`` (new or replacing the same ids, keeping tags and notes) in one transaction;
        ``session`` marks that folder imported in the same transaction. Rows of one id are one swatch (two captures
        of one image: a still imported twice); the last of them is written, as a later import's would be."""
        rows = list({r.id: r for r in rows}.values())
        imported = _now()
        swatch_sql = ("INSERT INTO swatches (id, kind, session, capture_id, captured, imported, image_path, record_path, "
                      "record_sha256, reliable, hair, sigma_r, sigma_g, sigma_b, record) "
                      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (id) DO UPDATE SET "
                      "kind = excluded.kind, session = excluded.session, capture_id = excluded.capture_id, "
                      "captured = excluded.captured, imported = excluded.imported, image_path = excluded.image_path, "
                      "record_path = excluded.record_path, record_sha256 = excluded.record_sha256, "
                      "reliable = excluded.reliable, hair = excluded.hair, sigma_r = excluded.sigma_r, "
                      "sigma_g = excluded.sigma_g, sigma_b = excluded.sigma_b, record = excluded.record")
        swatches, colours = [], []
        for r in rows:
            if r.kind not in KINDS:
                raise LibraryError(f"swatch {r.id}: kind {r.kind!r} is not one of {', '.join(KINDS)}")
            sigma = r.sigma_a or (None, None, None)
            swatches.append((r.id, r.kind, r.session, r.capture_id, r.captured, imported, r.image_path, r.record_path,
                             r.record_sha256, int(bool(r.reliable)),
                             None if r.hair is None else json.dumps(r.hair.to_dict()),
                             *(None if s is None else float(s) for s in sigma), json.dumps(r.record.to_json())))
            colours += [(r.id, ill, *map(float, lab)) for ill, lab in r.labs.items()]
        with self.db.transaction():
            self.db.executemany(swatch_sql, swatches)
            ids = [(r.id,) for r in rows]
            self.db.executemany("DELETE FROM colours WHERE swatch_id = ?", ids)
            self.db.executemany("INSERT INTO colours (swatch_id, illuminant, l, a, b) VALUES (?, ?, ?, ?, ?)", colours)
            if session is not None:
                self.db.execute("INSERT INTO sessions (path, imported, captures) VALUES (?, ?, ?) ON CONFLICT (path) "
                                "DO UPDATE SET imported = excluded.imported, captures = excluded.captures",
                                (session, imported, len(rows)))
        return len(rows)

    def resolve(self, key: str) -> str:
        """The full id of the one swatch whose id (or capture id) starts with ``key``."""
        key = key.strip().lstrip("#")
        rows = self.db.query("SELECT id FROM swatches WHERE id LIKE ? ESCAPE '\\' OR capture_id = ? LIMIT 2",
                             (like_escape(key) + "%", key))
        if not rows:
            raise LibraryError(f"no swatch {key!r} in the library; see hairdigi library find")
        if len(rows) > 1:
            raise LibraryError(f"{key!r} names more than one swatch; give more of its id")
        return rows[0][0]

    def tag(self, key: str, tags: list[str], remove: bool = False) -> tuple[str, ...]:
        """Add (or remove) tags; the swatch's tags after."""
        swatch_id = self.resolve(key)
        clean = [t.strip() for t in tags if t.strip()]
        if not clean:
            raise LibraryError("give at least one non-empty tag")
        with self.db.transaction():
            if remove:
                self.db.executemany("DELETE FROM tags WHERE swatch_id = ? AND tag = ?", [(swatch_id, t) for t in clean])
            else:
                self.db.executemany("INSERT INTO tags (swatch_id, tag) VALUES (?, ?) ON CONFLICT DO NOTHING",
                                    [(swatch_id, t) for t in clean])
        return self.tags_of(swatch_id)

    def note(self, key: str, text: str) -> str:
        swatch_id = self.resolve(key)
        with self.db.transaction():
            self.db.execute("UPDATE swatches SET note = ? WHERE id = ?", (text, swatch_id))
        return swatch_id

    def add_readings(self, rows: list[tuple], source: str) -> int:
        """Replace the readings of ``source`` (a file's name) with ``rows`` of (tress, geometry, observer,
        illuminant, L*, a*, b*, line), in one transaction."""
        imported = _now()
        with self.db.transaction():
            self.db.execute("DELETE FROM readings WHERE source = ?", (source,))
            self.db.executemany("INSERT INTO readings (tress, geometry, observer, illuminant, l, a, b, source, line, "
                                "imported) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                                [(*r[:7], source, r[7], imported) for r in rows])
        return len(rows)

    def readings(self, tress: str | None = None) -> list[tuple]:
        """The lab's readings as (tress, geometry, observer, illuminant, L*, a*, b*, source, line); of one tress, or all."""
        where, params = ("WHERE tress = ?", (tress,)) if tress is not None else ("", ())
        return [tuple(r) for r in self.db.query(f"SELECT tress, geometry, observer, illuminant, l, a, b, source, line "
                                                 f"FROM readings {where} ORDER BY tress, source, line", params)]

    def swatches_of(self, tress: str) -> list[Swatch]:
        """The swatches a lab's tress id names: by swatch id, capture id or tag, exactly."""
        return self._swatches("WHERE id = ? OR capture_id = ? OR id IN (SELECT swatch_id FROM tags WHERE tag = ?) "
                              "ORDER BY id", (tress, tress, tress))

    def set_setting(self, key: str, value: str) -> None:
        with self.db.transaction():
            self.db.execute("INSERT INTO settings (key, value) VALUES (?, ?) ON CONFLICT (key) "
                            "DO UPDATE SET value = excluded.value", (key, value))

    def setting(self, key: str) -> str | None:
        rows = self.db.query("SELECT value FROM settings WHERE key = ?", (key,))
        return rows[0][0] if rows else None

    # -- reads ------------------------------------------------------------------------------
    def count(self) -> int:
        return int(self.db.query("SELECT COUNT(*) FROM swatches")[0][0])

    def sessions(self) -> list[tuple[str, str, int]]:
        return [tuple(r) for r in self.db.query("SELECT path, imported, captures FROM sessions ORDER BY path")]

    def tags_of(self, swatch_id: str) -> tuple[str, ...]:
        return tuple(r[0] for r in self.db.query("SELECT tag FROM tags WHERE swatch_id = ? ORDER BY tag", (swatch_id,)))

    _COLUMNS = ("swatches.id, kind, session, capture_id, captured, imported, image_path, record_path, reliable, "
                "hair, sigma_r, sigma_g, sigma_b, note")

    def _swatches(self, where: str = "", params: tuple = ()) -> list[Swatch]:
        rows = self.db.query(f"SELECT {self._COLUMNS} FROM swatches {where}", params)   # in the order asked
        if not rows:
            return []
        ids = [r[0] for r in rows]
        tags: dict[str, list[str]] = {}
        labs: dict[str, dict] = {}
        for chunk in range(0, len(ids), 500):
            part = ids[chunk:chunk + 500]
            marks = ", ".join("?" * len(part))
            for sid, tag in self.db.query(f"SELECT swatch_id, tag FROM tags WHERE swatch_id IN ({marks}) ORDER BY tag", part):
                tags.setdefault(sid, []).append(tag)
            for sid, ill, l, a, b in self.db.query(
                    f"SELECT swatch_id, illuminant, l, a, b FROM colours WHERE swatch_id IN ({marks})", part):
                labs.setdefault(sid, {})[ill] = (l, a, b)
        out = []
        for (sid, kind, session, cap, captured, imported, image, record, reliable, hair, r, g, b, note) in rows:
            try:
                params = _hair(sid, hair)
            except LibraryError as exc:    # one damaged row does not hide the others: listed without parameters
                logging.getLogger(__name__).warning("%s", exc)
                params, reliable = None, False
            out.append(Swatch(sid, kind, session, cap, captured, imported, image, record, bool(reliable),
                              params, None if r is None else (r, g, b), note or "",
                              tuple(tags.get(sid, ())), labs.get(sid, {})))
        return out

    def record(self, key: str) -> SwatchRecord:
        """The records of the one swatch ``key`` names, as imported (:meth:`SwatchRecord.from_json`)."""
        swatch_id = self.resolve(key)
        data = self.db.query("SELECT record FROM swatches WHERE id = ?", (swatch_id,))[0][0]
        try:
            return SwatchRecord.from_json(json.loads(data))
        except (ValueError, RecordError) as exc:     # json's errors are ValueErrors
            raise LibraryError(f"swatch {swatch_id}: its stored record cannot be read ({exc}); import its session "
                               f"or record file again (hairdigi library import)") from None

    def get(self, key: str) -> Swatch:
        return self._swatches("WHERE id = ?", (self.resolve(key),))[0]

    def all(self, text: str = "", order: str = "captured", limit: int | None = None) -> list[Swatch]:
        """Swatches whose id, capture, session, note or a tag contains ``text``, newest first or by colour
        (lightness under daylight, light to dark, swatches without a colour last); at most ``limit``."""
        where, params = "", ()
        if text:
            like = f"%{like_escape(text)}%"
            where = ("WHERE id LIKE ? ESCAPE '\\' OR capture_id LIKE ? ESCAPE '\\' OR session LIKE ? ESCAPE '\\' "
                     "OR note LIKE ? ESCAPE '\\' OR id IN (SELECT swatch_id FROM tags WHERE tag LIKE ? ESCAPE '\\')")
            params = (like,) * 5
        if order == "colour":
            where = ("LEFT JOIN colours ON colours.swatch_id = swatches.id AND colours.illuminant = 'daylight' "
                     f"{where} ORDER BY CASE WHEN colours.l IS NULL THEN 1 ELSE 0 END, colours.l DESC, id")
        else:
            where += " ORDER BY COALESCE(captured, imported) DESC, id"
        if limit is not None:
            where += f" LIMIT {max(0, int(limit))}"
        return self._swatches(where, params)

    def find(self, lab: np.ndarray, under: str = "daylight", k: int = 10) -> list[tuple[Swatch, float]]:
        """The ``k`` swatches nearest ``lab`` (CIELAB) under ``under``, by ΔE2000 of the mean colour.

        Exact, through the lightness index: CIEDE2000 is at least |ΔL*| / S_L and S_L <= SL_MAX, so a
        swatch further than ``SL_MAX * d`` in L* cannot beat a distance ``d`` already found; the band
        of L* read widens until the k-th distance fits in it.
        """
        if under not in COLOURS:
            raise LibraryError(f"unknown light or reading {under!r}; choose one of {', '.join(COLOURS)}")
        lab = np.asarray(lab, float)
        if int(k) < 1:
            raise LibraryError(f"k {k}: ask for at least one match")
        k = int(k)
        band = FIRST_BAND
        while True:
            rows = self.db.query("SELECT swatch_id, l, a, b FROM colours WHERE illuminant = ? AND l BETWEEN ? AND ?",
                                 (under, float(lab[0] - band), float(lab[0] + band)))
            de = delta_e(np.array([r[1:] for r in rows], float), lab[None, :]) if rows else np.zeros(0)
            enough = len(rows) >= k and np.partition(de, k - 1)[k - 1] * SL_MAX <= band
            if enough or band >= 200.0:      # L* spans 0-100: a band of 200 holds every swatch
                break
            band = max(2 * band, float(np.partition(de, k - 1)[k - 1]) * SL_MAX if len(rows) >= k else 0.0)
        if not rows:
            return []
        ids = [r[0] for r in rows]
        best = np.argsort(de, kind="stable")[:k]
        chosen = [ids[i] for i in best]
        marks = ", ".join("?" * len(chosen))
        by_id = {s.id: s for s in self._swatches(f"WHERE id IN ({marks})", tuple(chosen))}
        return [(by_id[ids[i]], float(de[i])) for i in best]

    def integrity(self) -> list[str]:
        """Problems found: SQLite's own check, and colours or tags of swatches that are not there."""
        problems = []
        if not self.db.postgres:
            problems += [r[0] for r in self.db.query("PRAGMA integrity_check") if r[0] != "ok"]
        orphans = self.db.query("SELECT COUNT(*) FROM colours WHERE swatch_id NOT IN (SELECT id FROM swatches)")[0][0]
        if orphans:
            problems.append(f"{orphans} colours of missing swatches")
        return problems


def open_library(where: str | None = None) -> Library:
    """The library at ``where`` (default: :func:`location`), migrated to this hairdigi's schema."""
    return Library(where)
