"""Klipper through Moonraker's HTTP API (``shared/reference/firmware.md`` §5.5), with urllib only.

``POST /printer/gcode/script`` with ``{"script": "line1\\nline2"}`` answers ``{"result": "ok"}`` once
every line has run, or an error object. Console replies (such as the ``SET_INPUT_SHAPER`` report)
are read back from ``GET /server/gcode_store?count=N``. An API key goes in the ``X-Api-Key``
header; neither it nor credentials or tokens in the URL are ever logged (:func:`redact`).
"""

from __future__ import annotations

import base64
import json
import urllib.error
import urllib.request
from typing import Callable
from urllib.parse import quote, urlsplit, urlunsplit

from ringtune.hardware.link import LinkError, LinkTimeout, redact
from ringtune.shaping.errors import RingtuneError


class Moonraker:
    """A Moonraker server at ``url`` (``http://host:7125``; credentials in it are used, not shown)."""

    def __init__(self, url: str, api_key: str | None = None, timeout: float = 10.0,
                 log: Callable[[str], None] | None = None):
        parts = urlsplit(url)
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise RingtuneError("must be an http:// or https:// URL", f"--moonraker {redact(url)}")
        self.base = urlunsplit((parts.scheme, parts.netloc.rsplit("@", 1)[-1], parts.path.rstrip("/"), "", ""))
        self.shown = redact(url)
        self.query = parts.query
        self.user = parts.username
        self.password = parts.password
        self.api_key = api_key
        self.timeout = timeout
        self.log = log or (lambda msg: None)

    def _request(self, method: str, path: str, body: dict | None = None) -> dict:
        payload = self._open(method, path, body)
        try:
            return json.loads(payload)
        except json.JSONDecodeError:
            raise LinkError(f"{path} did not answer JSON", self.shown) from None

    def download(self, root: str, path: str) -> bytes:
        """A file's bytes through the file API, ``GET /server/files/<root>/<path>``."""
        return self._open("GET", f"/server/files/{quote(root)}/{quote(path)}", None)

    def list_files(self, root: str) -> list[dict]:
        """Every file of a root, ``GET /server/files/list?root=<root>``: ``[{path (relative to the
        root), modified (s since the epoch), size (bytes), permissions}]``."""
        result = self._request("GET", f"/server/files/list?root={quote(root)}").get("result")
        return [f for f in result if isinstance(f, dict) and "path" in f] if isinstance(result, list) else []

    def _http_request(self, method: str, path: str, body: dict | None) -> urllib.request.Request:
        """The HTTP request: JSON body, API key or basic-auth header, the URL's own query kept."""
        url = self.base + path
        if self.query:
            url += ("&" if "?" in url else "?") + self.query
        data = json.dumps(body).encode() if body is not None else None
        req = urllib.request.Request(url, data=data, method=method)
        req.add_header("Accept", "application/json")
        if data is not None:
            req.add_header("Content-Type", "application/json")
        if self.api_key:
            req.add_header("X-Api-Key", self.api_key)
        if self.user is not None:
            token = base64.b64encode(f"{self.user}:{self.password or ''}".encode()).decode()
            req.add_header("Authorization", f"Basic {token}")
        return req

    def _open(self, method: str, path: str, body: dict | None) -> bytes:
        """The answer's bytes (errors as :class:`LinkError`, Moonraker's own message kept)."""
        req = self._http_request(method, path, body)
        self.log(f"{method} {redact(req.full_url)}")     # credentials are not in self.base; tokens redacted
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as resp:
                return resp.read()
        except urllib.error.HTTPError as exc:
            msg = _error_message(exc)
            err = LinkError(f"HTTP {exc.code} from {path}: {msg or exc.reason}", self.shown)
            err.message = msg      # Klipper's own words (e.g. "Unsupported shaper type: ei2")
            raise err from None
        except (TimeoutError, urllib.error.URLError) as exc:
            if isinstance(getattr(exc, "reason", exc), TimeoutError):     # itself, or a URLError's reason
                raise LinkTimeout(f"no answer from {path} within {self.timeout:g} s", path, self.shown) from None
            raise LinkError(f"cannot reach Moonraker: {exc.reason}", self.shown) from None

    def script(self, lines: str | list[str]) -> None:
        """Run G-code lines; returns when all have completed (LinkError if one fails)."""
        text = lines if isinstance(lines, str) else "\n".join(lines)
        result = self._request("POST", "/printer/gcode/script", {"script": text})
        if result.get("result") != "ok":
            raise LinkError(f"unexpected answer {str(result)[:80]!r}", self.shown)

    def state(self) -> dict:
        """Klippy's state through ``GET /printer/info``: ``{"state": "ready" | "shutdown" | "error" |
        "startup", "message": state_message}`` (``unknown`` when Moonraker cannot say)."""
        try:
            info = self._request("GET", "/printer/info").get("result", {})
        except LinkTimeout:
            raise
        except LinkError as exc:
            return {"state": "unknown", "message": exc.bare}
        return {"state": str(info.get("state", "unknown")), "message": str(info.get("state_message", ""))}

    def _gcode_store(self, count: int) -> list[dict]:
        """The last ``count`` items of the console store, ``GET /server/gcode_store?count=N``."""
        result = self._request("GET", f"/server/gcode_store?count={int(count)}")
        return [item for item in result.get("result", {}).get("gcode_store", []) if isinstance(item, dict)]

    def console(self, count: int = 50, since: float | None = None) -> list[str]:
        """The last ``count`` console messages (commands and responses), only those stored after
        Moonraker's time ``since`` (see :meth:`newest`) when given."""
        return [str(item.get("message", "")) for item in self._gcode_store(count)
                if since is None or float(item.get("time", 0.0)) > since]

    def newest(self) -> float:
        """Moonraker's time of the newest console message (0 when there is none): what was stored
        before a command, so that its replies are told from those of earlier ones."""
        store = self._gcode_store(1)
        return float(store[-1].get("time", 0.0)) if store else 0.0

    def query_objects(self, objects: dict[str, list[str] | None]) -> dict:
        """``GET /printer/objects/query``: ``{object: {attribute: value}}`` for each object (the
        attributes listed, or all of them for ``None``)."""
        args = "&".join(quote(name, safe=" ").replace(" ", "%20")
                        + ("=" + ",".join(attrs) if attrs else "") for name, attrs in objects.items())
        result = self._request("GET", f"/printer/objects/query?{args}")
        status = result.get("result", {}).get("status") if isinstance(result, dict) else None
        if not isinstance(status, dict):
            raise LinkError(f"unexpected answer to objects/query {str(result)[:80]!r}", self.shown)
        return status


def _error_message(exc: urllib.error.HTTPError) -> str | None:
    """Moonraker's own message in an HTTP error's JSON body (``{"error": {"message": …}}``), if any."""
    try:
        err = json.loads(exc.read() or b"{}").get("error", {})
    except (json.JSONDecodeError, AttributeError):
        return None
    return err.get("message") if isinstance(err, dict) else str(err)
