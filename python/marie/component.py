"""component: a marie component in Python, with the contract of core/component.c: ports bound by
the system file, parameters from NAME.params.yaml, --help and --describe, the eight lifecycle
functions obeyed only when signed with the system's key, a heartbeat with its counters, the
simulator's clock, checked decode, and push, pull (through a Mailbox) and event ports.

The configuration (options, environment, system file, profiles, the checks and their
file:line:col errors) is resolved by libmarie itself, through marie-resolve: one reader of
system files, the same answers as a C component's."""
import heapq
import json
import os
import selectors
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
import traceback

from . import auth, params as params_mod, types
from .bus import Bus, BusError

IN, OUT = "in", "out"
PUSH, PULL, EVENT = "push", "pull", "event"
STATES = ("created", "ready", "running", "paused", "failed", "exited", "degraded")
CREATED, READY, RUNNING, PAUSED, FAILED, EXITED, DEGRADED = range(7)
COMMANDS = (None, "init", "start", "stop", "pause", "resume", "restart", "abort", "quit")
SPEC_MARKER = "marie-component-describe/1"
EVENT_QUEUE_MAX = 256
WANT_EVERY_US = 500_000     # an input on a ring's channel asks this often (the writer holds 2 s)
SEV_DEBUG, SEV_INFO, SEV_WARN, SEV_ERROR = range(4)
LOG_LEVELS = {"debug": 0, "info": 1, "warn": 2, "error": 3, "off": 4}


class Refused(Exception):
    """Raised by a hook to refuse its transition; the reply and the heartbeat carry the reason."""


class PullError(Exception):
    """A pull without a value: .status is 'timeout', 'empty', 'unknown_channel' or 'bad_reply'."""

    def __init__(self, status, why=""):
        super().__init__(why or status)
        self.status = status


def wall_us():
    return time.time_ns() // 1000


def mono_us():
    return time.monotonic_ns() // 1000


class Port:
    """A port as declared (class level); Component binds a copy per instance."""

    def __init__(self, name, type=None, direction=IN, mech=PUSH, channel=None):
        self.name, self.type_name, self.dir, self.mech, self.default_channel = name, type, direction, mech, channel
        self.c = None
        self.channel = None
        self.type = None
        self.cb = None
        self.msgs = 0
        self.seq = 0            # ringless notices sent
        self.too_big = 0
        self.queue = []

    def _bind(self, c, channel, bus, ring=0):
        """ring: the channel's max_size where the system file puts it on shared memory or the
        fast path, else 0."""
        p = Port(self.name, self.type_name, self.dir, self.mech, self.default_channel)
        p.c, p.channel, p.bus, p.ring = c, channel, bus, ring
        p.type = types.find(self.type_name) if self.type_name else None
        return p

    def new(self, **fields):
        """A message of the port's type with these fields set."""
        return self.type.new(**fields)

    def publish(self, msg):
        """Encode (a message of the port's type, or bytes on a raw port) and publish; False when
        the kernel refused it (counted as a drop)."""
        if self.dir != OUT:
            raise ValueError("port %s is an input" % self.name)
        if self.type is not None and msg.__class__ is self.type.cls:
            data = msg.encode()
        elif isinstance(msg, (bytes, bytearray)):
            data = bytes(msg)
        else:
            raise TypeError("port %s carries %s, not %s" % (self.name, self.type.name if self.type else "raw bytes",
                                                            type(msg).__name__))
        why = self._announce(data) if self.ring else None
        if why or not self.bus.publish(self.channel, data):
            self.c.drops += 1
            self.c.count(why or "publish_failed")
            return False
        self.c.msgs_out += 1
        self.msgs += 1
        return True

    def _announce(self, data):
        """A channel on shared memory or the fast path: a notice without a ring on CHANNEL.SHM says
        the message follows on CHANNEL, where the C readers take it (docs/python.md). None, or
        the counter of the reason it was not sent."""
        if len(data) > self.ring:
            if not self.too_big:
                self.c.log("warn", "%d bytes on %s: larger than its transport's max_size (%d); such messages "
                           "are counted publish_too_big" % (len(data), self.channel, self.ring))
            self.too_big += 1
            return "publish_too_big"
        if len(data) < 8:       # no type fingerprint: the readers would refuse it
            return "publish_failed"
        self.seq += 1
        n = types.find("marie.shm_notice_t").new(utime=wall_us(), host=self.c.shm_host, segment="", seq=self.seq,
                                                 size=len(data), fingerprint=struct.unpack(">q", data[:8])[0])
        return None if self.bus.publish(self.channel + ".SHM", n.encode()) else "publish_failed"

    def _want(self):
        """An input on shared memory or the fast path asks for the messages on CHANNEL, as a
        subscriber on another host does."""
        w = types.find("marie.shm_want_t").new(utime=wall_us(), host=self.c.shm_host, requester=self.c.name)
        self.bus.publish(self.channel + ".SHMWANT", w.encode())

    def on_message(self, cb):
        """cb(msg, info) for every message (push: while running; event: held while not running,
        delivered in order on start/resume). info has channel, recv_utime and raw."""
        if self.dir != IN or self.mech == PULL:
            raise ValueError("port %s does not take handlers" % self.name)
        self.cb = cb

    def pull(self, timeout_ms=100):
        """The newest value of the port's channel from its Mailbox: (msg, age_us). Other messages
        and timers are served meanwhile. PullError when there is none."""
        out = []
        self.pull_async(timeout_ms, lambda status, msg, age: out.append((status, msg, age)))
        c = self.c
        while not out and not c._quitting:
            c._run_once(10)
        if not out:
            raise PullError("timeout", "quitting")
        status, msg, age = out[0]
        if status != "ok":
            raise PullError(status)
        return msg, age

    def pull_async(self, timeout_ms, cb):
        """cb(status, msg, age_us) exactly once: status 'ok', 'timeout', 'empty',
        'unknown_channel' or 'bad_reply'."""
        if self.mech != PULL:
            raise ValueError("port %s is not a pull port" % self.name)
        self.c._pull_send(self, timeout_ms, cb)


def In(name, type=None, mech=PUSH, channel=None):
    return Port(name, type, IN, mech, channel)


def Out(name, type=None, mech=PUSH, channel=None):
    return Port(name, type, OUT, mech, channel)


class MsgInfo:
    __slots__ = ("channel", "recv_utime", "raw")

    def __init__(self, channel, recv_utime, raw):
        self.channel, self.recv_utime, self.raw = channel, recv_utime, raw


class Params:
    """Parameter values as attributes (params.rate_hz)."""

    def __init__(self, values):
        self.__dict__.update(values)

    def __repr__(self):
        return "Params(%r)" % self.__dict__


class _Timer:
    __slots__ = ("period", "deadline", "cb", "sim", "wanted", "oneshot", "alive")


class Component:
    """Subclass it: kind, ports (In/Out), params (a NAME.params.yaml beside the class's file, or a
    list of {"name", "type", "default", "help"}), and the hooks on_init, on_start, on_stop,
    on_pause, on_resume, on_abort, on_quit (raise Refused("why") to refuse), on_param(name,
    value) for dynamic parameters. Then marie.main(TheClass)."""
    kind = None
    ports = ()
    params = None
    params_table = None

    # ---- declaration ----

    @classmethod
    def _param_specs(cls):
        if cls.params is None:
            return []
        if isinstance(cls.params, str):
            base = os.path.dirname(os.path.abspath(sys.modules[cls.__module__].__file__))
            return params_mod.load(os.path.join(base, cls.params), cls.params_table)
        return [dict({"help": "", "default": None, "dynamic": False}, **p) for p in cls.params]

    @classmethod
    def describe(cls):
        """The description marie-am checks system files against (core/spec.h's format)."""
        return {"describe": SPEC_MARKER, "kind": cls.kind or cls.__name__,
                "ports": [{"name": p.name, "dir": p.dir, "mech": p.mech, "type": types_name(p.type_name),
                           "channel": p.default_channel} for p in cls.ports],
                "params": [{"name": q["name"], "type": q["type"], "default": q["default"], "help": q["help"],
                            "dynamic": q.get("dynamic", False)} for q in cls._param_specs()]}

    @classmethod
    def usage(cls):
        d = cls.describe()
        lines = ["usage: %s [--system FILE] [--name NAME] [--profile P] [--url URL] [--clock wall|sim]" % d["kind"],
                 "       [--param KEY=VALUE]... [--port PORT=CHANNEL]... [--hold] [--describe] [--version]",
                 "ports:"]
        for p in d["ports"]:
            lines.append("  %-16s %-4s %-6s %-28s default channel %s" % (
                p["name"], p["dir"], p["mech"], p["type"] or "raw", p["channel"] or "(must be bound)"))
        lines.append("params:")
        for q in d["params"]:
            lines.append("  %-20s default %-12s %s%s" % (q["name"], q["default"] if q["default"] is not None
                                                          else "(required)", q["help"],
                                                          " (dynamic)" if q["dynamic"] else ""))
        return "\n".join(lines) + "\n"

    # ---- creation ----

    def __init__(self, argv=None):
        argv = list(sys.argv[1:] if argv is None else argv)
        self.cfg = resolve(type(self).describe(), argv)
        self.name = self.cfg["name"]
        self.host = os.environ.get("MARIE_HOST") or self.cfg["host"]
        self.group = self.cfg["group"]
        for d in os.environ.get("MARIE_TYPES_PATH", "").split(":") + self.cfg["types"]:
            if d:
                types.add_path(d)
        self.key = auth.load_key(self.cfg["key_file"]) if self.cfg["key_file"] else None
        self.replay = auth.Replay()
        self.sim = self.cfg["clock"] == "sim"
        self.sim_now = None
        self.state = CREATED
        self.reason = ""
        self.fail_reason = ""
        self.degraded = False
        self.degraded_reason = ""
        self.initialised = False
        self.hold = self.cfg["hold"]
        self.start_mono = mono_us()
        self.msgs_in = self.msgs_out = self.drops = self.bad_inputs = self.overruns = 0
        self.counters = {}
        self.hb_seq = self.event_seq = self.request_id = 0
        self._quitting = False
        self._timers = []
        self._sim_timers = []
        self._sim_waiting = []
        self._every = {}
        self._timer_seq = 0
        self._pulls = {}
        self._warned = {}
        self._log_level = LOG_LEVELS.get(os.environ.get("MARIE_LOG", "info"), 1)
        self._dynamic = {q["name"] for q in type(self)._param_specs() if q.get("dynamic")}
        self.params = Params(self.cfg["params"])
        self.sel = selectors.DefaultSelector()
        self.buses = {}
        self.shm_host = os.environ.get("MARIE_SHM_HOST") or socket.gethostname() or "localhost"
        self.bus = self._bus_for(self.cfg["url"])
        self._ports = {}
        for p in type(self).ports:
            b = self.cfg["ports"][p.name]
            bp = p._bind(self, b["channel"], self._bus_for(b["url"]), b["max_size"] if b["shm"] else 0)
            self._ports[p.name] = bp
            if bp.dir == IN and bp.mech != PULL:
                bp.bus.subscribe(bp.channel, lambda ch, data, ut, bp=bp: self._port_receive(bp, data, ut))
                if bp.ring:
                    bp._want()
                    self._add_timer(WANT_EVERY_US, lambda overruns, bp=bp: bp._want(), sim=False, wanted=False)
        self.reply_channel = "MARIE_REPLY.%s.%d" % (self.name, os.getpid())
        self.bus.subscribe("MARIE_LIFECYCLE", self._on_lifecycle)
        self.bus.subscribe(self.reply_channel, self._on_pull_reply)
        self.bus.subscribe("MARIE_PARAM", self._on_param_request)
        if self.sim:
            self.bus.subscribe("MARIE_CLOCK", self._on_clock)
        self._add_timer(self._heartbeat_period(), lambda overruns: self.heartbeat(), sim=False, wanted=False)

    def _bus_for(self, url):
        if url not in self.buses:
            try:
                b = Bus(url)
            except (BusError, OSError) as e:
                raise SystemExit("%s: cannot open the LCM bus '%s': %s" % (self.name, url, e))
            self.buses[url] = b
            self.sel.register(b, selectors.EVENT_READ, b)
        return self.buses[url]

    def _heartbeat_period(self):
        t = self.cfg["heartbeat_timeout_s"]
        p = int(t / 4 * 1e6) if 0 < t < 4 else 1_000_000
        return max(p, 20_000)

    # ---- accessors ----

    def port(self, name):
        return self._ports[name]

    def now(self):
        """Microseconds on the configured clock: the simulator's (0 before its first message) or
        the wall's."""
        return (self.sim_now or 0) if self.sim else wall_us()

    def clock_known(self):
        return not self.sim or self.sim_now is not None

    # ---- counters, logging, events ----

    def count(self, counter, delta=1):
        self.counters[counter] = self.counters.get(counter, 0) + delta

    def counter(self, counter):
        return self.counters.get(counter, 0)

    def log(self, level, text):
        if LOG_LEVELS[level] >= self._log_level:
            t = time.localtime()
            sys.stderr.write("%02d:%02d:%02d.%03d %s %s %s: %s\n" % (t.tm_hour, t.tm_min, t.tm_sec,
                             int(time.time() * 1000) % 1000, self.name, level, self.kind_name(), text))
            sys.stderr.flush()

    def kind_name(self):
        return type(self).kind or type(self).__name__

    def bad_input(self, counter, text):
        """Bad input: counted (the heartbeat's bad_input and the named counter), logged at most
        every 5 s."""
        self.bad_inputs += 1
        if counter:
            self.count(counter)
        now = time.monotonic()
        if now - self._warned.get("bad", -10) >= 5:
            self._warned["bad"] = now
            self.log("warn", "%s: bad input (%s, %d so far): %s" % (self.name, counter, self.bad_inputs, text))

    def event(self, severity, kind, text):
        ev = types.find("marie.event_t").new(utime=wall_us(), source=self.name, severity=severity, kind=kind,
                                             text=text)
        self.event_seq += 1
        ev.seq = self.event_seq
        if not self.bus.publish("MARIE_EVENT", ev.encode()):
            self.drops += 1
        self.log("error" if severity >= SEV_ERROR else "warn" if severity >= SEV_WARN else "info",
                 "event %s: %s" % (kind, text))

    def set_degraded(self, degraded, reason=""):
        self.degraded_reason = reason
        if degraded != self.degraded:
            self.degraded = degraded
            self.log("warn" if degraded else "info", "%s: %s (%s)" % (
                self.name, "degraded" if degraded else "no longer degraded", reason))
            self.heartbeat()

    def heartbeat(self):
        hbt = types.find("marie.heartbeat_t")
        hb = hbt.new()
        degraded = self.degraded and self.state == RUNNING
        hb.utime, hb.component, hb.host, hb.pid = wall_us(), self.name, self.host, os.getpid()
        self.hb_seq += 1
        hb.seq = self.hb_seq
        hb.state = DEGRADED if degraded else self.state
        hb.reason = self.degraded_reason if degraded else self.reason
        hb.uptime_us = mono_us() - self.start_mono
        bus_bad = sum(b.stats["bad_datagrams"] for b in self.buses.values())
        lost = sum(b.stats["given_up"] for b in self.buses.values())
        hb.msgs_in, hb.msgs_out, hb.drops = self.msgs_in, self.msgs_out, self.drops + lost
        hb.bad_input, hb.overruns = self.bad_inputs + bus_bad, self.overruns
        ct = types.find("marie.counter_t")
        hb.counters = [ct.new(name=k, value=v) for k, v in list(self.counters.items())[:64]]
        hb.ncounters = len(hb.counters)
        pst = types.find("marie.port_status_t")
        hb.ports = [pst.new(name=p.name, channel=p.channel, type=p.type.name if p.type else "",
                            direction=1 if p.dir == OUT else 0, msgs=p.msgs) for p in self._ports.values()][:64]
        hb.nports = len(hb.ports)
        self.bus.publish("MARIE_HEARTBEAT", hb.encode())

    # ---- timers ----

    def every(self, hz, cb):
        """cb(overruns) at hz while the component runs, on its clock; a late tick runs once and
        counts the periods it missed as overruns. Asked again for the same callback, the same
        timer at the new rate."""
        if not hz > 0:
            raise ValueError("every: hz must be > 0")
        t = self._every.get(cb)
        if t is not None and t.alive:
            t.period = int(1e6 / hz)
            return t
        t = self._every[cb] = self._add_timer(int(1e6 / hz), cb, sim=self.sim, wanted=True)
        return t

    def after(self, seconds, cb):
        """cb() once, after `seconds` of wall time (whatever the clock)."""
        return self._add_timer(int(seconds * 1e6), lambda overruns: cb(), sim=False, wanted=False, oneshot=True)

    def cancel(self, timer):
        timer.alive = False

    def _add_timer(self, period, cb, sim, wanted, oneshot=False):
        t = _Timer()
        t.period, t.cb, t.sim, t.wanted, t.oneshot, t.alive = period, cb, sim, wanted, oneshot, True
        if sim and self.sim_now is None:
            self._sim_waiting.append(t)     # counts from the first clock message
            return t
        t.deadline = (self.sim_now if sim else mono_us()) + period
        self._push(t)
        return t

    def _push(self, t):
        self._timer_seq += 1
        heapq.heappush(self._sim_timers if t.sim else self._timers, (t.deadline, self._timer_seq, t))

    def _clock_heard(self):
        for t in self._sim_waiting:
            t.deadline = self.sim_now + t.period
            self._push(t)
        self._sim_waiting = []

    def _fire_timers(self):
        """Runs what is due: timers on the monotonic clock, then those on the simulator's."""
        self._fire_heap(self._timers, mono_us)
        if self.sim_now is not None:
            self._fire_heap(self._sim_timers, lambda: self.sim_now)

    def _fire_heap(self, heap, now_fn):
        later = []
        while heap:
            due, _, t = heap[0]
            if not t.alive:
                heapq.heappop(heap)
                continue
            now = now_fn()
            if now < due:
                break
            heapq.heappop(heap)
            overruns = (now - t.deadline) // t.period
            if t.oneshot:
                t.alive = False
            else:
                t.deadline += (overruns + 1) * t.period
                later.append(t)
            if t.wanted and self.state != RUNNING:
                continue
            if t.wanted:
                self.overruns += overruns
            t.cb(overruns)
        for t in later:
            self._push(t)

    def _next_wait(self, cap_ms):
        while self._timers and not self._timers[0][2].alive:
            heapq.heappop(self._timers)
        if not self._timers:
            return cap_ms
        return min(cap_ms, max(0, (self._timers[0][0] - mono_us()) / 1000))

    # ---- the loop ----

    def _run_once(self, cap_ms):
        wait = self._next_wait(cap_ms)
        for key, _ in self.sel.select(wait / 1000):
            if key.data is self._wake:
                try:
                    key.fileobj.recv(64)
                except OSError:
                    pass
                continue
            key.data.handle()
        self._fire_timers()
        if self._signalled:
            self._signalled = False
            self.log("info", "%s: signal: quit" % self.name)
            self.command(8)

    def run(self):
        """Until quit; returns the exit status (0)."""
        self._signalled = False
        rd, wr = socket.socketpair()
        rd.setblocking(False)
        wr.setblocking(False)
        self._wake = object()
        self.sel.register(rd, selectors.EVENT_READ, self._wake)
        signal.set_wakeup_fd(wr.fileno(), warn_on_full_buffer=False)

        def on_signal(signo, frame):
            self._signalled = True
        for s in (signal.SIGTERM, signal.SIGINT):
            signal.signal(s, on_signal)
        self.heartbeat()
        if not self.hold:
            ok, why = self.command(1)
            if ok:
                ok, why = self.command(2)
            if not ok:
                self.log("error", "%s: %s" % (self.name, why))
                self.event(SEV_ERROR, "start_failed", why)
                if self.state != FAILED:
                    self._set_state(FAILED, why)
        while not self._quitting:
            self._run_once(1000)
        return 0

    # ---- lifecycle ----

    def _set_state(self, s, why):
        self.state = s
        self.reason = why
        self.heartbeat()

    def _hook(self, name, what):
        fn = getattr(self, name, None)
        if fn is None:
            return True
        try:
            rc = fn()
        except Refused as e:
            self.reason = "%s failed: %s" % (what, e or "refused")
            return False
        except Exception as e:      # a hook that crashes refuses; the reason says where
            self.log("error", "%s: %s" % (name, traceback.format_exc().strip()))
            self.reason = "%s failed: %s: %s" % (what, type(e).__name__, e)
            return False
        if rc is False:
            self.reason = "%s failed: refused" % what
            return False
        return True

    def _quit_hook(self):
        if self.initialised:
            self._hook("on_quit", "quit")
        self.initialised = False

    def command(self, cmd):
        """Drive the lifecycle in-process, as an order would: (ok, reason)."""
        s = self.state
        name = COMMANDS[cmd] if 1 <= cmd <= 8 else "unknown"
        if s == EXITED:
            self.reason = "%s refused: the component has exited" % name
            return False, self.reason
        if cmd == 1 and s in (CREATED, FAILED):
            if s == FAILED:
                self._quit_hook()
            if not self._hook("on_init", "init"):
                return False, self.reason
            self.initialised = True
            self._set_state(READY, "init")
            return True, "ok"
        if cmd == 2 and s == READY:
            if not self._hook("on_start", "start"):
                return False, self.reason
            self._set_state(RUNNING, "start")
            self._flush_events()
            return True, "ok"
        if cmd == 3 and s in (RUNNING, PAUSED):
            if not self._hook("on_stop", "stop"):
                return False, self.reason
            self._set_state(READY, "stop")
            return True, "ok"
        if cmd == 4 and s == RUNNING:
            if not self._hook("on_pause", "pause"):
                return False, self.reason
            self._set_state(PAUSED, "pause")
            return True, "ok"
        if cmd == 5 and s == PAUSED:
            if not self._hook("on_resume", "resume"):
                return False, self.reason
            self._set_state(RUNNING, "resume")
            self._flush_events()
            return True, "ok"
        if cmd == 6 and s != CREATED:
            if s in (RUNNING, PAUSED) and not self._hook("on_stop", "stop"):
                return False, self.reason
            if s == FAILED:
                self._quit_hook()
                if not self._hook("on_init", "init"):
                    self._set_state(FAILED, self.reason)
                    return False, self.reason
                self.initialised = True
            if not self._hook("on_start", "start"):
                self._set_state(READY, self.reason)
                return False, self.reason
            self._set_state(RUNNING, "restart")
            self._flush_events()
            return True, "ok"
        if cmd == 7:
            if self.initialised:
                self._hook("on_abort", "abort")
            self._set_state(FAILED, "abort")
            return True, "ok"
        if cmd == 8:
            if s in (RUNNING, PAUSED):
                self._hook("on_stop", "stop")
            self._quit_hook()
            self._set_state(EXITED, "quit")
            self._quitting = True
            return True, "ok"
        if not 1 <= cmd <= 8:
            self.reason = "unknown command %d" % cmd
        else:
            self.reason = "%s refused in state %s" % (name, STATES[s])
        return False, self.reason

    def _reply(self, request_id, cmd, ok, why):
        r = types.find("marie.lifecycle_reply_t").new(utime=wall_us(), request_id=request_id, component=self.name,
                                                      command=cmd, ok=ok, state=self.state, reason=why)
        self.bus.publish("MARIE_LIFECYCLE_REPLY", r.encode())

    def _targets_me(self, target):
        return target in ("*", self.name) or (self.group is not None and target == self.group)

    def _on_lifecycle(self, channel, data, utime):
        try:
            cmd = types.find("marie.lifecycle_command_t").decode(data, finite=False)
        except types.BadMessage:
            self.bad_input("bad_lifecycle", "undecodable lifecycle command (%d bytes)" % len(data))
            self._reply(-1, 0, False, "malformed lifecycle command")
            return
        if not self._targets_me(cmd.target):
            return
        verdict = auth.check(self.key, self.replay, cmd) if self.key else "ok"
        ok, why = False, "ok"
        if verdict != "ok":
            why = "order refused: %s" % verdict
            self.bad_input("refused_orders", "%s %s from %s" % (why, COMMANDS[cmd.command] if 1 <= cmd.command <= 8
                                                                 else "unknown", cmd.sender))
        elif not 1 <= cmd.command <= 8:
            self.bad_input("bad_lifecycle", "unknown lifecycle command %d" % cmd.command)
            why = "unknown command"
        else:
            ok, why = self.command(cmd.command)
            if not ok:
                self.count("refused_commands")
            self.log("info", "%s: %s from %s: %s" % (self.name, COMMANDS[cmd.command], cmd.sender,
                                                     "ok" if ok else why))
        self._reply(cmd.request_id, cmd.command, ok, "ok" if ok else why)

    def _on_clock(self, channel, data, utime):
        try:
            clk = types.find("marie.sim_clock_t").decode(data)
        except types.BadMessage:
            self.bad_input("bad_clock", "malformed or non-finite clock message (%d bytes)" % len(data))
            return
        known = self.sim_now is not None
        self.sim_now = clk.utime
        if not known:
            self._clock_heard()

    # ---- parameters at run time (marie param) ----

    def _param_reply(self, rq, ok, why, names=()):
        vt = types.find("marie.param_value_t")
        specs = {q["name"]: q for q in type(self)._param_specs()}
        vals = [vt.new(name=n, type=specs[n]["type"], value=_ParamService.text(getattr(self.params, n), specs[n]["type"]),
                       dynamic=specs[n].get("dynamic", False), help=specs[n]["help"] or "") for n in names] if ok else []
        r = types.find("marie.param_reply_t").new(utime=wall_us(), request_id=rq.request_id, component=self.name,
                                                  op=rq.op, ok=ok, reason=why, nparams=len(vals), params=vals)
        self.bus.publish("MARIE_PARAM_REPLY", r.encode())

    def _on_param_request(self, channel, data, utime):
        try:
            rq = types.find("marie.param_request_t").decode(data, finite=False)
        except types.BadMessage:
            self.bad_input("bad_param_request", "undecodable parameter request (%d bytes)" % len(data))
            return
        if rq.target != self.name:
            return
        specs = {q["name"]: q for q in type(self)._param_specs()}
        if rq.op == 1:
            return self._param_reply(rq, True, "ok", list(specs))
        if rq.op not in (2, 3):
            return self._param_reply(rq, False, "unknown operation")
        if rq.name not in specs:
            return self._param_reply(rq, False, "no such parameter")
        if rq.op == 2:
            return self._param_reply(rq, True, "ok", [rq.name])
        verdict = auth.check(self.key, self.replay, rq) if self.key else "ok"
        if verdict != "ok":
            self.bad_input("refused_orders", "param set %s from %s: order refused: %s" % (rq.name, rq.sender, verdict))
            return self._param_reply(rq, False, "order refused: %s" % verdict)
        if rq.name not in self._dynamic:
            return self._param_reply(rq, False, "parameter '%s' is not dynamic: %s reads it at init (set it in the "
                                     "system file or with --param, then restart)" % (rq.name, self.kind_name()))
        try:
            value = _ParamService.parse(rq.value, specs[rq.name]["type"])
        except Exception as e:
            return self._param_reply(rq, False, "%s: %s" % (rq.name, e))
        old = getattr(self.params, rq.name)
        setattr(self.params, rq.name, value)
        hook = getattr(self, "on_param", None)
        try:
            if hook is not None:
                hook(rq.name, value)
        except Exception as e:
            setattr(self.params, rq.name, old)
            return self._param_reply(rq, False, "refused: %s" % e)
        self.count("params_set")
        self.log("info", "%s: parameter %s set to %s by %s" % (self.name, rq.name, rq.value, rq.sender))
        self._param_reply(rq, True, "ok", [rq.name])

    # ---- ports ----

    def _port_receive(self, p, data, utime):
        if p.cb is None:
            return
        if self.state == RUNNING:
            self._deliver(p, data, utime)
        elif p.mech != EVENT:
            self.count("ignored_not_running")
        else:
            if len(p.queue) == EVENT_QUEUE_MAX:
                p.queue.pop(0)
                self.drops += 1
                self.count("events_lost")
            p.queue.append((data, utime))

    def _deliver(self, p, data, utime):
        msg = None
        if p.type is not None:
            try:
                msg = p.type.decode(data)
            except types.BadMessage as e:
                self.bad_input(e.counter, "port %s: %d bytes on %s: not a well-formed, finite %s"
                               % (p.name, len(data), p.channel, p.type.name))
                return
        self.msgs_in += 1
        p.msgs += 1
        p.cb(msg, MsgInfo(p.channel, utime, data))

    def _flush_events(self):
        for p in self._ports.values():
            while p.queue and self.state == RUNNING:
                data, utime = p.queue.pop(0)
                self._deliver(p, data, utime)

    def _pull_send(self, p, timeout_ms, cb):
        self.request_id += 1
        rid = self.request_id
        req = types.find("marie.pull_request_t").new(utime=wall_us(), request_id=rid, requester=self.name,
                                                     channel=p.channel, reply_channel=self.reply_channel,
                                                     timeout_ms=timeout_ms)
        if not p.bus.publish(p.channel + ".PULL", req.encode()):
            self.drops += 1
            cb("bad_reply", None, 0)
            return

        def on_timeout():
            if self._pulls.pop(rid, None) is not None:
                self.count("pull_timeouts")
                cb("timeout", None, 0)
        self.msgs_out += 1
        self._pulls[rid] = (p, cb, self.after(timeout_ms / 1000, on_timeout))

    def _on_pull_reply(self, channel, data, utime):
        try:
            r = types.find("marie.pull_reply_t").decode(data, finite=False)
        except types.BadMessage:
            self.bad_input("bad_pull_reply", "undecodable pull reply")
            return
        entry = self._pulls.pop(r.request_id, None)
        if entry is None:
            self.count("late_pull_replies")
            return
        p, cb, timer = entry
        self.cancel(timer)
        if r.status in (1, 4):
            return cb("empty", None, r.age_us)
        if r.status != 0:
            return cb("unknown_channel" if r.status == 2 else "bad_reply", None, r.age_us)
        msg = None
        if p.type is not None:
            try:
                msg = p.type.decode(bytes(r.data))
            except types.BadMessage as e:
                self.bad_input(e.counter, "pull reply on %s: %d bytes: not a well-formed, finite %s"
                               % (r.channel, r.size, p.type.name))
                return cb("bad_reply", None, r.age_us)
        self.msgs_in += 1
        p.msgs += 1
        cb("ok", msg if p.type is not None else bytes(r.data), r.age_us)


class _ParamService:
    """marie param: list, get and set (parameters declared `dynamic`, then on_param(name, value),
    which may raise Refused), as core/component_params.c answers for C components."""

    @staticmethod
    def text(v, ptype):
        if ptype == "bool":
            return "true" if v else "false"
        if ptype == "double":
            return repr(float(v))
        return "" if v is None else str(v)

    @staticmethod
    def parse(text, ptype):
        import yaml
        v = yaml.safe_load(text) if text else ""
        if ptype == "int" and (isinstance(v, bool) or not isinstance(v, int)):
            raise ValueError("expected an integer, got '%s'" % text)
        if ptype == "double":
            if isinstance(v, bool) or not isinstance(v, (int, float)) or v != v or v in (float("inf"), float("-inf")):
                raise ValueError("expected a finite number, got '%s'" % text)
            v = float(v)
        if ptype == "bool" and not isinstance(v, bool):
            raise ValueError("expected true or false, got '%s'" % text)
        if ptype == "string":
            v = text
        return v


def types_name(t):
    if t is None:
        return None
    return t if "." in t else "marie." + t


def find_resolve():
    """marie-resolve: $MARIE_RESOLVE, beside the python/ folder in a build tree, or on PATH."""
    env = os.environ.get("MARIE_RESOLVE")
    if env:
        return env
    here = os.path.dirname(os.path.abspath(__file__))
    for cand in (os.path.join(here, "..", "..", "build", "bin", "marie-resolve"),
                 os.path.join(os.path.dirname(os.path.abspath(sys.argv[0])), "marie-resolve")):
        if os.access(cand, os.X_OK):
            return os.path.normpath(cand)
    found = shutil.which("marie-resolve")
    if not found:
        raise SystemExit("marie: marie-resolve not found (set MARIE_RESOLVE, or put marie's bin/ on PATH)")
    return found


def resolve(description, argv):
    """The component's configuration as libmarie reads it; exits with its status and errors."""
    r = subprocess.run([find_resolve()] + argv, input=json.dumps(description).encode(), capture_output=True)
    if r.returncode != 0:
        sys.stderr.write(r.stderr.decode("utf-8", "replace"))
        raise SystemExit(r.returncode)
    return json.loads(r.stdout.decode("utf-8", "replace"))


def main(cls, argv=None):
    """Run a component class as a program: --help, --describe and --version answered here, the
    rest by the runtime. Returns the exit status (0 after quit, 2 for configuration errors)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--help" in argv or "-h" in argv:
        sys.stdout.write(cls.usage())
        return 0
    if "--describe" in argv:
        sys.stdout.write(json.dumps(cls.describe()) + "\n")
        return 0
    if "--version" in argv:
        from . import __version__
        sys.stdout.write("%s (marie %s, Python)\n" % (cls.kind or cls.__name__, __version__))
        return 0
    try:
        c = cls(argv)
    except params_mod.ParamsError as e:
        sys.stderr.write("%s\n" % e)
        return 2
    except (auth.KeyError_, KeyError) as e:
        sys.stderr.write("%s\n" % (e.args[0] if e.args else e))
        return 2
    return c.run()
