"""A fake printer for push tests: Marlin (classic and FT_MOTION), Prusa, RRF and Klipper, over a
pseudo-tty or loopback TCP, plus a fake Moonraker HTTP server on 127.0.0.1.

The firmware side follows ``shared/reference/firmware.md`` §5: Marlin checks line numbers and XOR
checksums and asks ``Resend:`` (optionally followed by ``ok``); RRF silently drops a line with a
bad checksum; Klipper ignores numbers and checksums. Faults are injected at given received-line
indices (0-based, counting every numbered line the printer receives, handshakes included):

- ``corrupt``: a byte of the received line is flipped before it is checked (line noise);
- ``resend``: the line is dropped and ``Resend: <n>`` / ``rs <n>`` asked for it;
- ``busy``: ``echo:busy: processing`` lines for ``busy_s`` seconds before the ok;
- ``temps``: a temperature report before the reply; ``garbage``: a line of random bytes;
- ``noise``: line noise glued to the front of the protocol lines answering that line (``ok``,
  ``start``, ``Resend:``), as a board resetting through its bootloader at another baud rate sends;
- ``reset``: the printer reboots instead of executing the line (says ``start``, loses settings);
- ``hang_after``: after that many executed commands, it never answers again.

``executed`` lists the commands carried out since the last reset (what is "applied").
"""

from __future__ import annotations

import json
import os
import re
import select
import socket
import threading
import time
import tty
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, urlsplit

TEMP_REPORT = " T:210.00 /210.00 B:60.00 /60.00 @:0 B@:0"
#: line noise (non-ASCII bytes and a NUL) glued in front of a protocol line by ``Faults.noise``
NOISE = bytes([0xFF, 0xE0, 0x00, 0x9C, 0x80])
_PROTOCOL_LINE = re.compile(r"^(ok|start|Resend:|rs )")


@dataclass
class Faults:
    corrupt: set = field(default_factory=set)
    resend: set = field(default_factory=set)
    busy: set = field(default_factory=set)
    temps: set = field(default_factory=set)
    garbage: set = field(default_factory=set)
    reset: set = field(default_factory=set)
    noise: set = field(default_factory=set)
    hang_after: int | None = None
    busy_s: float = 0.0
    ok_after_resend: bool = True


# -- firmware cores: command text -> (reply lines, error or None) ------------------------------------

def _params(cmd: str) -> dict[str, str]:
    out = {}
    for m in re.finditer(r'([A-Z])("[^"]*"|[^\s"]*)', cmd.split(None, 1)[1] if " " in cmd else ""):
        out[m.group(1)] = m.group(2).strip('"')
    return out


class MarlinCore:
    """Marlin classic ZV (M593 X/Y F D), M201 F S, M204 P R T S (report ``  M204 P.. R.. T..``,
    Marlin ``M200-M205.cpp``), M500, M105. ``input_shaping=False``: a build without it (M593 is
    then an unknown command, ``gcode.cpp``); ``min_freq``: the build's lowest shaper frequency
    (``M593.cpp``: ``?Frequency (F) must be greater than <min> or 0 to disable``)."""

    def __init__(self, input_shaping: bool = True, min_freq: float = 0.0):
        self.input_shaping = input_shaping
        self.min_freq = min_freq
        self.reset()
        self.eeprom = None

    def reset(self):
        self.shaping = {"x": [40.0, 0.15], "y": [40.0, 0.15]}
        self.limit = (0.0, 5)
        self.accel = {"P": 1500.0, "R": 1500.0, "T": 3000.0}
        self.max_accel = {"X": 500.0, "Y": 500.0, "Z": 100.0, "E": 5000.0}   # an Ender-3 V2's M201

    def move_accel(self, dx: float, dy: float, de: float = 0.0) -> float:
        """The acceleration (mm/s²) Marlin's planner gives a move (planner.cpp _populate_block, equal
        steps/mm): a retraction at R; else P (with E steps) or T, capped per axis by M201."""
        if dx == 0 and dy == 0:
            return self.accel["R"]
        accel = self.accel["P"] if de else self.accel["T"]
        total = max(abs(dx), abs(dy), abs(de))
        for ax, d in (("X", dx), ("Y", dy), ("E", de)):
            if d and self.max_accel[ax] < accel:
                accel = min(accel, self.max_accel[ax] * total / abs(d))
        return accel

    def execute(self, cmd: str):
        word = cmd.split()[0].upper()
        p = _params(cmd)
        if word == "M593" and self.input_shaping:
            axes = [a.lower() for a in "XY" if a in p] or ["x", "y"]
            if "F" in p and 0 < float(p["F"]) <= self.min_freq:
                return [], f"?Frequency (F) must be greater than {self.min_freq:.2f} or 0 to disable"
            if "F" not in p and "D" not in p:
                return ["echo:Input Shaping:"] + [f"echo:  M593 {a.upper()} F{self.shaping[a][0]:.2f} "
                                                   f"D{self.shaping[a][1]:.2f}" for a in ("x", "y")], None
            if "D" in p and not 0 <= float(p["D"]) <= 1:
                return [], "?Zeta (D) value out of range (0-1)"
            for a in axes:
                if "F" in p:
                    self.shaping[a][0] = float(p["F"])
                if "D" in p:
                    self.shaping[a][1] = float(p["D"])
            return [], None
        if word == "M201":
            if not p:                                  # M201_report (Marlin M200-M205.cpp)
                m = self.max_accel
                return ["echo:; Maximum Acceleration (units/s2):",
                        f"echo:  M201 X{m['X']:.2f} Y{m['Y']:.2f} Z{m['Z']:.2f} E{m['E']:.2f}"], None
            self.limit = (float(p.get("F", self.limit[0])), int(float(p.get("S", self.limit[1]))))
            for k in "XYZE":
                if k in p:
                    self.max_accel[k] = float(int(float(p[k])))     # uint32_t max_acceleration_mm_per_s2
            return [], None
        if word == "M204":
            if not {"P", "R", "S", "T"} & set(p):
                return ["echo:; Acceleration (units/s2) (P<print-accel> R<retract-accel> T<travel-accel>):",
                        f"echo:  M204 P{self.accel['P']:.2f} R{self.accel['R']:.2f} T{self.accel['T']:.2f}"], None
            if "S" in p:
                self.accel["P"] = self.accel["T"] = float(p["S"])
            for k in ("P", "R", "T"):
                if k in p:
                    self.accel[k] = float(p[k])
            return [], None
        if word == "M500":
            self.eeprom = self.snapshot()
            return ["echo:Settings Stored (700 bytes; crc 1234)"], None
        if word == "M105":
            return ["__ok__" + TEMP_REPORT], None
        if word == "M110":
            return [], None
        return [f'echo:Unknown command: "{cmd}"'], None

    def snapshot(self):
        return json.loads(json.dumps({k: v for k, v in vars(self).items() if k != "eeprom"}))


class FtmCore(MarlinCore):
    """Marlin FT_MOTION: M493."""

    def reset(self):
        super().reset()
        self.ftm = {"on": 0, "x": [0, 37.0, 0.1, 0.05], "y": [0, 37.0, 0.1, 0.05]}

    def execute(self, cmd: str):
        if cmd.split()[0].upper() != "M493":
            return super().execute(cmd)
        p = _params(cmd)
        axes = [a.lower() for a in "XY" if a in p] or ["x", "y"]
        if not p:
            lines = [f"M493 S{self.ftm['on']} D0 H0"]
            for a in ("x", "y"):
                c, f, z, q = self.ftm[a]
                lines.append(f"M493 {a.upper()} C{c} A{f:.2f} F0.00 I{z:.2f} Q{q:.2f}")
            return lines, None
        if "S" in p:
            self.ftm["on"] = int(float(p["S"]))
        if "C" in p and not 0 <= int(float(p["C"])) <= 8:
            return [], "?Invalid (C)ompensator value. (0-8)"
        for a in axes:
            for letter, k in (("C", 0), ("A", 1), ("I", 2), ("Q", 3)):
                if letter in p:
                    self.ftm[a][k] = int(float(p[letter])) if letter == "C" else float(p[letter])
        return [], None


class PrusaCore(MarlinCore):
    """Prusa Buddy M593 X/Y T F D R W."""

    TYPES = ["ZV", "ZVD", "MZV", "EI", "EI_2HUMP", "EI_3HUMP"]

    def reset(self):
        super().reset()
        self.ps = {"x": [2, 50.7, 0.1, 20.0], "y": [2, 40.6, 0.1, 20.0]}

    def execute(self, cmd: str):
        if cmd.split()[0].upper() != "M593":
            return super().execute(cmd)
        p = _params(cmd)
        if "W" in p:
            self.eeprom = self.snapshot()
            return [], None
        axes = [a.lower() for a in "XY" if a in p] or ["x", "y"]
        if not ({"T", "F", "D", "R"} & set(p)):
            out = []
            for a in ("x", "y"):
                t, f, d, r = self.ps[a]
                out.append(f"axis {a.upper()} disabled" if f == 0 else
                           f"axis {a.upper()} type={self.TYPES[t]} freq={f:.2f} damp={d:.2f} vr={r:.2f}")
            return out + ["axis Z disabled"], None
        for a in axes:
            for letter, k in (("T", 0), ("F", 1), ("D", 2), ("R", 3)):
                if letter in p:
                    self.ps[a][k] = int(p[letter]) if letter == "T" else float(p[letter])
        return [], None


class RrfCore:
    """RepRapFirmware 3.6 M593."""

    def __init__(self):
        self.reset()

    def reset(self):
        self.m593 = {"P": "none", "F": 40.0, "S": 0.05}
        self.accel = {"P": 10000.0, "T": 10000.0}
        self.max_accel = {"X": 3000.0, "Y": 3000.0, "Z": 100.0, "E": 5000.0}

    def execute(self, cmd: str):
        word = cmd.split()[0].upper()
        p = _params(cmd)
        if word == "M593":
            if not p:
                if self.m593["P"] == "none":
                    return ["Input shaping is disabled"], None
                return [f"Input shaping '{self.m593['P']}' at {self.m593['F']:.1f}Hz damping factor "
                        f"{self.m593['S']:.2f}, impulses 0.250 0.500 with delays (ms) 0.00 12.50 25.00"], None
            if "F" in p and float(p["F"]) < 4:
                return [], "M593: parameter 'F' too low"
            for k in ("P", "F", "S"):
                if k in p:
                    self.m593[k] = p[k].lower() if k == "P" else float(p[k])
            return [], None
        if word == "M201":          # RRF GCodes2.cpp: report "Accelerations (mm/sec^2): X: .., Y: .., ..."
            if not p:
                m = self.max_accel
                return [f"Accelerations (mm/sec^2): X: {m['X']:.1f}, Y: {m['Y']:.1f}, Z: {m['Z']:.1f}, "
                        f"E: {m['E']:.1f}"], None
            for k in "XYZE":
                if k in p:
                    self.max_accel[k] = float(p[k])
            return [], None
        if word == "M204":          # RRF Move.cpp: P printing, T travel, S both
            if not {"P", "S", "T"} & set(p):
                return [f"Maximum printing acceleration {self.accel['P']:.1f}, maximum travel acceleration "
                        f"{self.accel['T']:.1f} mm/sec^2"], None
            if "S" in p:
                self.accel["P"] = self.accel["T"] = float(p["S"])
            for k in ("P", "T"):
                if k in p:
                    self.accel[k] = float(p[k])
            return [], None
        if word == "M110":
            return [], None
        return [], f"Unknown command {word}"


class KlipperCore:
    """Klipper SET_INPUT_SHAPER (always reports, per axis), SET_VELOCITY_LIMIT (reports when given
    no parameter), STATUS. ``input_shaper=False``: a printer.cfg without ``[input_shaper]``, where
    SET_INPUT_SHAPER is an unknown command (answered with an info line, as Klipper does)."""

    def __init__(self, input_shaper: bool = True, shutdown_on: str | None = None):
        self.input_shaper = input_shaper
        self.shutdown_on = shutdown_on          # a command that shuts the printer down (as M112 does)
        self.reset()

    def reset(self):
        self.axes = {"x": ["mzv", 0.0, 0.1], "y": ["mzv", 0.0, 0.1]}
        self.max_accel = 3000.0
        self.state = ("ready", "Printer is ready")

    def execute(self, cmd: str):
        cmd = re.sub(r"^N\d+\s+", "", cmd)
        cmd = re.sub(r"\*\d+$", "", cmd)
        parts = cmd.split()
        if not parts:
            return [], None
        if self.shutdown_on and parts[0].upper() == self.shutdown_on:
            self.state = ("shutdown", "Shutdown due to M112 command\nOnce the underlying issue is corrected, "
                          "use the \"FIRMWARE_RESTART\" command to reset the firmware, reload the\nconfig, "
                          "and restart the host software.\nPrinter is shutdown")
        if self.state[0] != "ready":
            return [], self.state[1].splitlines()[0]
        if parts[0].upper() == "SET_VELOCITY_LIMIT":
            kv = dict(p.split("=", 1) for p in parts[1:] if "=" in p)
            if "ACCEL" in kv:
                self.max_accel = float(kv["ACCEL"])
            if kv:
                return [], None
            return [f"// max_velocity: 300.000000\n// max_accel: {self.max_accel:.6f}\n"
                    "// minimum_cruise_ratio: 0.500000\n// square_corner_velocity: 5.000000"], None
        if parts[0].upper() == "STATUS":
            return ["// Klipper state: Ready"], None
        if parts[0].upper() == "SET_INPUT_SHAPER" and self.input_shaper:
            kv = dict(p.split("=", 1) for p in parts[1:] if "=" in p)
            for k, v in kv.items():
                m = re.match(r"(SHAPER_FREQ|DAMPING_RATIO|SHAPER_TYPE)_([XY])$", k.upper())
                if not m:
                    return [], f"Unknown parameter {k}"
                a = m.group(2).lower()
                idx = {"SHAPER_TYPE": 0, "SHAPER_FREQ": 1, "DAMPING_RATIO": 2}[m.group(1)]
                self.axes[a][idx] = v.lower() if idx == 0 else float(v)
            return [f"// shaper_type_{a}:{t} shaper_freq_{a}:{f:.3f} damping_ratio_{a}:{d:.6f}"
                    for a, (t, f, d) in self.axes.items()], None
        if parts[0].upper() in ("M110", "M115"):
            return ([] if parts[0].upper() == "M110" else ["ok FIRMWARE_NAME:Klipper"]), None
        return [f"// Unknown command:\"{parts[0].upper()}\""], None


CORES = {"marlin": MarlinCore, "marlin-ftm": FtmCore, "prusa": PrusaCore, "rrf": RrfCore,
         "klipper": KlipperCore}


# -- the serial side ------------------------------------------------------------------------------------

class FakePrinter:
    """A printer on a pty (``transport="pty"``) or on 127.0.0.1 TCP (``"tcp"``); use ``.url``."""

    def __init__(self, firmware: str = "marlin", faults: Faults | None = None, transport: str = "pty",
                 seed: int = 0, core=None):
        self.firmware = firmware
        self.protocol = "rrf" if firmware == "rrf" else "klipper" if firmware == "klipper" else "marlin"
        self.core = core or CORES[firmware]()
        self.faults = faults or Faults()
        self.transport = transport
        self.executed: list[str] = []
        self.sessions: list[list[str]] = [self.executed]
        self.received = 0
        self.last_n = 0
        self.resets = 0
        self._stop = threading.Event()
        self._seed = seed
        self._noisy = False
        if transport == "pty":
            self._master, slave = os.openpty()
            tty.setraw(slave)
            self.url = os.ttyname(slave)
            self._slave = slave
        else:
            self._srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            self._srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._srv.bind(("127.0.0.1", 0))
            self._srv.listen(1)
            self._srv.settimeout(0.1)
            self.url = f"socket://127.0.0.1:{self._srv.getsockname()[1]}"
            self._conn = None
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(timeout=2)
        if self.transport == "pty":
            os.close(self._master)
            os.close(self._slave)
        else:
            if self._conn:
                self._conn.close()
            self._srv.close()

    # I/O
    def _recv(self) -> bytes:
        if self.transport == "pty":
            r, _, _ = select.select([self._master], [], [], 0.05)
            if not r:
                return b""
            try:
                return os.read(self._master, 4096)
            except OSError:
                return b""
        if self._conn is None:
            try:
                self._conn, _ = self._srv.accept()
                self._conn.settimeout(0.05)
            except (socket.timeout, OSError):
                return b""
        try:
            data = self._conn.recv(4096)
        except socket.timeout:
            return b""
        except OSError:
            data = b""
        if not data:
            self._conn.close()
            self._conn = None
        return data

    def write(self, text: str | bytes) -> None:
        data = text if isinstance(text, bytes) else (text + "\n").encode()
        if self._noisy and isinstance(text, str) and _PROTOCOL_LINE.match(text):
            data = NOISE + data
        if self.transport == "pty":
            os.write(self._master, data)
        elif self._conn is not None:
            try:
                self._conn.sendall(data)
            except OSError:
                pass

    def _run(self):
        buf = b""
        while not self._stop.is_set():
            buf += self._recv()
            while b"\n" in buf:
                raw, _, buf = buf.partition(b"\n")
                self._line(raw.decode("ascii", "replace").strip())

    # protocol
    def _line(self, line: str) -> None:
        if not line:
            return
        if self.faults.hang_after is not None and len(self.executed) >= self.faults.hang_after:
            return
        if self.protocol == "klipper":
            self._execute(line)
            return
        i = self.received
        self.received += 1
        self._noisy = i in self.faults.noise
        if i in self.faults.garbage:
            self.write(bytes([0xFF, 0xFE, 0x00, 0x9C]) + b"#%$garbage\x07\r\n")
        if i in self.faults.temps:
            self.write(TEMP_REPORT)
        if i in self.faults.corrupt:
            pos = len(line) // 2
            line = line[:pos] + chr(ord(line[pos]) ^ 0x01) + line[pos + 1:]
        m = re.match(r"^N(-?\d+)\s+(.*?)\*(\d+)$", line)
        if not m:
            if line.startswith("N"):
                if self.protocol == "marlin":
                    self._ask_resend("No Checksum with line number")
                return
            self._execute(line)
            return
        n, cmd, cs = int(m.group(1)), m.group(2), int(m.group(3))
        body = line[:line.rindex("*")].encode()
        calc = 0
        for b in body:
            calc ^= b
        if calc != cs:
            if self.protocol == "marlin":
                self._ask_resend("checksum mismatch")
            return  # RRF: dropped silently
        if "M110" not in cmd and self.protocol == "marlin" and n != self.last_n + 1:
            self._ask_resend("Line Number is not Last Line Number+1")
            return
        if i in self.faults.resend:
            if self.protocol == "marlin":
                self.write(f"Resend: {self.last_n + 1}")
                if self.faults.ok_after_resend:
                    self.write("ok")
            else:
                self.write(f"rs {n}")
            return
        if i in self.faults.reset:
            self.resets += 1
            self.core.reset()
            self.last_n = 0
            self.executed = []
            self.sessions.append(self.executed)
            time.sleep(0.05)
            self.write("start")
            self.write("echo: External Reset")
            return
        if "M110" in cmd:
            self.last_n = int(re.findall(r"N(-?\d+)", line)[-1])
        else:
            self.last_n = n
        self._execute(cmd, busy=i in self.faults.busy)

    def _ask_resend(self, why: str) -> None:
        self.write(f"Error:{why}, Last Line: {self.last_n}")
        self.write(f"Resend: {self.last_n + 1}")
        if self.faults.ok_after_resend:
            self.write("ok")

    def _execute(self, cmd: str, busy: bool = False) -> None:
        if busy:
            end = time.monotonic() + self.faults.busy_s
            while time.monotonic() < end:
                self.write("echo:busy: processing")
                time.sleep(min(0.3, self.faults.busy_s / 3))
        if not cmd.upper().startswith("M110"):
            self.executed.append(cmd)
        lines, err = self.core.execute(cmd)
        ok = "ok"
        for ln in lines:
            if ln.startswith("__ok__"):
                ok = "ok" + ln[6:]
            elif ln.startswith("ok ") and self.protocol == "klipper":
                ok = ln
            else:
                self.write(ln)
        if err and err.startswith("?") and self.protocol == "marlin":
            self.write(err)                      # Marlin prints a rejected parameter as is, then ok
        elif err:
            self.write(("!! " if self.protocol == "klipper" else "Error:" if self.protocol == "marlin"
                        else "Error: ") + err)
        self.write(ok)


# -- Moonraker ---------------------------------------------------------------------------------------

class FakeMoonraker:
    """``POST /printer/gcode/script`` and ``GET /server/gcode_store`` on 127.0.0.1 (Klipper core).

    ``hang_after``: after that many scripts have run, every request is left without an answer
    (until the server is closed), like a Klippy that stopped responding behind Moonraker."""

    def __init__(self, api_key: str | None = None, hang_after: int | None = None, core=None):
        self.hang_after = hang_after
        self._release = threading.Event()
        self.core = core or KlipperCore()
        self.store: list[dict] = []
        self.scripts: list[str] = []
        self.requests: list[str] = []
        self.api_key = api_key
        fake = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args):
                pass

            def _reply(self, code: int, obj: dict):
                data = json.dumps(obj).encode()
                self.send_response(code)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def _auth(self) -> bool:
                if fake.hang_after is not None and len(fake.scripts) >= fake.hang_after:
                    fake._release.wait(30)
                    return False
                if fake.api_key and self.headers.get("X-Api-Key") != fake.api_key:
                    self._reply(401, {"error": {"code": 401, "message": "Unauthorized"}})
                    return False
                return True

            def do_POST(self):
                fake.requests.append(self.path)
                if not self._auth():
                    return
                url = urlsplit(self.path)
                if url.path != "/printer/gcode/script":
                    return self._reply(404, {"error": {"code": 404, "message": "Not Found"}})
                body = self.rfile.read(int(self.headers.get("Content-Length", 0)) or 0)
                try:
                    script = json.loads(body or b"{}").get("script")
                except json.JSONDecodeError:
                    script = None
                if script is None:
                    script = parse_qs(url.query).get("script", [None])[0]
                if script is None:
                    return self._reply(400, {"error": {"code": 400, "message": "No script"}})
                fake.scripts.append(script)
                for line in script.split("\n"):
                    fake.store.append({"message": line, "time": time.time(), "type": "command"})
                    lines, err = fake.core.execute(line)
                    for ln in lines:
                        fake.store.append({"message": ln, "time": time.time(), "type": "response"})
                    if err:
                        fake.store.append({"message": "!! " + err, "time": time.time(), "type": "response"})
                        return self._reply(400, {"error": {"code": 400, "message": err}})
                return self._reply(200, {"result": "ok"})

            def do_GET(self):
                fake.requests.append(self.path)
                if not self._auth():
                    return
                url = urlsplit(self.path)
                if url.path == "/printer/info":
                    state, message = getattr(fake.core, "state", ("ready", "Printer is ready"))
                    return self._reply(200, {"result": {"state": state, "state_message": message}})
                if url.path != "/server/gcode_store":
                    return self._reply(404, {"error": {"code": 404, "message": "Not Found"}})
                count = int(parse_qs(url.query).get("count", ["100"])[0])
                return self._reply(200, {"result": {"gcode_store": fake.store[-count:]}})

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}"
        self._thread = threading.Thread(target=self.server.serve_forever, kwargs={"poll_interval": 0.05},
                                        daemon=True)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._release.set()
        self.server.shutdown()
        self.server.server_close()
        self._thread.join(timeout=2)
