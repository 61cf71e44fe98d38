#!/usr/bin/python3
"""An independent Modbus TCP peer for the modbus-tcp stage: two position drives behind one TCP server.

Written from docs/rig-modbus.md alone (register map, status bits, word order, command semantics) on Debian's
python3-pymodbus, so vdrig's Modbus stage is tested against a device implementation this project's C++ did not
write. The drives follow the profile velocity/acceleration they are given (trapezoidal moves in real time).

Usage:  modbus_drive_peer.py [--units 1,2] [--word-order high-first|low-first] [--register-base 0]
                             [--home-time-s 0.05] [--port 0]
Prints "LISTENING <port>" on stdout once it accepts connections (port 0 = a free one the system picks).

Faults are driven from stdin, one command per line; "on_move DELAY_S <command>" arms a command that runs DELAY_S
after the next move command any drive accepts. Commands (UNIT is a drive's unit id):
  alarm UNIT CODE          latch a fault with CODE: the drive stops where it is, status bit 2 set
  stuck UNIT               the drive accepts moves but its motor does not turn (status "moving" stays set)
  exception UNIT CODE N    answer the next N requests to UNIT with Modbus exception CODE
  delay UNIT SECONDS N     answer the next N requests to UNIT SECONDS late
  refuse UNIT              the drive refuses commands: the command register keeps the value written
  stop_server              close every connection and stop listening (the drives keep their state)
  restart_server SECONDS   stop_server, then listen again on the same port SECONDS later
  query UNIT               print "STATE UNIT moving=0|1 position=COUNTS target=COUNTS fault=CODE"
  clear                    undo stuck/refuse/exception/delay
Every command is acknowledged with "OK <command>" on stdout.
"""
import argparse
import asyncio
import logging
import math
import sys
import threading
import time

from pymodbus.datastore import ModbusServerContext
from pymodbus.interfaces import IModbusSlaveContext
from pymodbus.server.async_io import ModbusConnectedRequestHandler, ModbusTcpServer

# docs/rig-modbus.md, "Register map": offsets from register_base.
PROFILE_VELOCITY, PROFILE_ACCEL, TARGET, COMMAND, STATUS, ACTUAL, FAULT = 0, 2, 4, 6, 7, 8, 10
REGISTER_COUNT = 11
CMD_MOVE, CMD_HOME, CMD_STOP, CMD_CLEAR_FAULT = 1, 2, 3, 4
IN_POSITION, HOMED, FAULTED, MOVING = 1, 2, 4, 8


def emit(line):
    print(line, flush=True)


class Drive(IModbusSlaveContext):
    """One position drive: a block of holding registers whose read side is computed from the simulated motion."""

    def __init__(self, unit, args):
        self.unit = unit
        self.base = args.register_base
        self.high_first = args.word_order == "high-first"
        self.home_time_s = args.home_time_s
        self.regs = [0] * REGISTER_COUNT
        self.position = 0.0  # counts, where the motion segment started
        self.target = 0
        self.start_time = time.monotonic()
        self.velocity = 0.0
        self.accel = 0.0
        self.moving = False
        self.homing_until = None
        self.homed = False
        self.fault = 0
        self.stuck = False
        self.refuse = False
        self.echo = None
        self.on_move = None  # callback(unit) when a move is accepted

    # -- 32-bit values in the configured word order
    def get_u32(self, offset):
        a, b = self.regs[offset], self.regs[offset + 1]
        return (a << 16 | b) if self.high_first else (b << 16 | a)

    def put_u32(self, offset, value):
        value &= 0xFFFFFFFF
        hi, lo = value >> 16, value & 0xFFFF
        self.regs[offset], self.regs[offset + 1] = (hi, lo) if self.high_first else (lo, hi)

    # -- motion
    def _offset_at(self, elapsed):
        """Distance covered `elapsed` s into a trapezoidal move of the current segment, and whether it is done."""
        distance = abs(self.target - self.position)
        v, a = self.velocity, self.accel
        if distance == 0 or v <= 0 or a <= 0:
            return distance, True
        t_ramp = v / a
        if a * t_ramp * t_ramp >= distance:  # triangle: never reaches v
            t_ramp = math.sqrt(distance / a)
            total = 2 * t_ramp
            v = a * t_ramp
        else:
            total = 2 * t_ramp + (distance - a * t_ramp * t_ramp) / v
        if elapsed >= total:
            return distance, True
        if elapsed < t_ramp:
            return 0.5 * a * elapsed * elapsed, False
        if elapsed > total - t_ramp:
            rest = total - elapsed
            return distance - 0.5 * a * rest * rest, False
        return 0.5 * a * t_ramp * t_ramp + v * (elapsed - t_ramp), False

    def current(self):
        now = time.monotonic()
        if self.homing_until is not None:
            if now >= self.homing_until:
                self.homing_until = None
                self.position, self.target, self.homed = 0.0, 0, True
                self.moving = False
            return self.position
        if not self.moving:
            return self.position
        if self.stuck:
            return self.position
        covered, done = self._offset_at(now - self.start_time)
        direction = 1.0 if self.target >= self.position else -1.0
        pos = self.position + direction * covered
        if done:
            self.position, self.moving = float(self.target), False
        return pos

    def halt(self):
        self.position = self.current()
        self.moving = False
        self.homing_until = None

    def latch_fault(self, code):
        self.halt()
        self.fault = code or 1

    def status(self):
        pos = self.current()
        word = 0
        if self.moving or self.homing_until is not None:
            word |= MOVING
        elif abs(pos - self.target) < 1:
            word |= IN_POSITION
        if self.homed:
            word |= HOMED
        if self.fault:
            word |= FAULTED
        return word, pos

    def execute_command(self, command):
        """Runs a command written to register 6; True when accepted (the register then reads 0)."""
        if self.refuse or command not in (CMD_MOVE, CMD_HOME, CMD_STOP, CMD_CLEAR_FAULT):
            return False
        if command == CMD_CLEAR_FAULT:
            self.fault = 0
            return True
        if command == CMD_STOP:
            self.halt()
            return True
        if self.fault:
            return False  # a latched fault refuses motion until cleared
        self.halt()
        if command == CMD_HOME:
            self.homing_until = time.monotonic() + self.home_time_s
            return True
        target = self.get_u32(TARGET)
        self.target = target - (1 << 32) if target >= 1 << 31 else target
        self.velocity = float(self.get_u32(PROFILE_VELOCITY))
        self.accel = float(self.get_u32(PROFILE_ACCEL))
        self.start_time = time.monotonic()
        self.moving = True
        if self.on_move:
            self.on_move(self.unit)
        return True

    # -- IModbusSlaveContext (holding registers only)
    def reset(self):
        self.regs = [0] * REGISTER_COUNT

    def validate(self, fc_as_hex, address, count=1):
        self.echo = None
        if fc_as_hex not in (3, 6, 16):
            return False
        offset = address - self.base
        if offset < 0 or offset + count > REGISTER_COUNT:
            return False
        if fc_as_hex in (6, 16) and offset + count > COMMAND + 1:
            return False  # status, position and fault code are read-only
        return True

    def getValues(self, fc_as_hex, address, count=1):
        offset = address - self.base
        if self.echo is not None and offset == COMMAND and count == 1:
            value, self.echo = self.echo, None  # FC6 echoes what was written
            return [value]
        word, pos = self.status()
        self.regs[STATUS] = word
        self.put_u32(ACTUAL, int(round(pos)))
        self.regs[FAULT] = self.fault
        return self.regs[offset:offset + count]

    def setValues(self, fc_as_hex, address, values):
        offset = address - self.base
        for i, v in enumerate(values):
            self.regs[offset + i] = v
        if offset <= COMMAND < offset + len(values):
            command = self.regs[COMMAND]
            self.echo = command if fc_as_hex == 6 else None
            if self.execute_command(command):
                self.regs[COMMAND] = 0


class Peer:
    def __init__(self, args):
        self.args = args
        units = [int(u) for u in args.units.split(",")]
        self.drives = {u: Drive(u, args) for u in units}
        for d in self.drives.values():
            d.on_move = self._moved
        self.exceptions = {}  # unit -> [code, remaining]
        self.delays = {}  # unit -> [seconds, remaining]
        self.armed = []  # (delay_s, command) run after the next move
        self.server = None
        self.port = args.port
        self.loop = None

    def _moved(self, unit):
        armed, self.armed = self.armed, []
        for delay_s, command in armed:
            self.loop.call_later(delay_s, self.run_command, command)

    def make_handler(self):
        peer = self

        class Handler(ModbusConnectedRequestHandler):
            def execute(self, request, *addr):
                unit = request.unit_id
                exc = peer.exceptions.get(unit)
                if exc and exc[1] > 0:
                    exc[1] -= 1
                    response = request.doException(exc[0])
                    response.transaction_id, response.unit_id = request.transaction_id, unit
                    self.send(response, *addr)
                    return
                late = peer.delays.get(unit)
                if late and late[1] > 0:
                    late[1] -= 1
                    # The request is executed now; only the answer is late (as a busy drive's would be).
                    real_send = self.send
                    self.send = lambda msg, *a, **kw: peer.loop.call_later(late[0], self._late_send, real_send, msg,
                                                                             a, kw)
                    try:
                        super().execute(request, *addr)
                    finally:
                        self.send = real_send
                    return
                super().execute(request, *addr)

            def _late_send(self, real_send, msg, a, kw):
                if self.running and not self.transport.is_closing():
                    real_send(msg, *a, **kw)

        return Handler

    async def start_server(self):
        context = ModbusServerContext(slaves=self.drives, single=False)
        self.server = ModbusTcpServer(context, address=("127.0.0.1", self.port), handler=self.make_handler(),
                                      allow_reuse_address=True, ignore_missing_slaves=True)
        asyncio.ensure_future(self.server.serve_forever())
        await self.server.serving
        self.port = self.server.server.sockets[0].getsockname()[1]

    async def stop_server(self):
        if self.server is None:
            return
        server, self.server = self.server, None
        for handler in list(server.active_connections.values()):
            handler.transport.abort()  # the client sees its connection reset, as when a drive's gateway dies
        await server.server_close()

    async def restart_server(self, seconds):
        await self.stop_server()
        await asyncio.sleep(seconds)
        await self.start_server()
        emit(f"LISTENING {self.port}")

    def run_command(self, line):
        words = line.split()
        if not words:
            return
        try:
            name, rest = words[0], words[1:]
            if name == "on_move":
                self.armed.append((float(rest[0]), " ".join(rest[1:])))
            elif name == "alarm":
                self.drives[int(rest[0])].latch_fault(int(rest[1]))
            elif name == "stuck":
                drive = self.drives[int(rest[0])]
                drive.halt()
                drive.stuck = True
                drive.moving = True
            elif name == "exception":
                self.exceptions[int(rest[0])] = [int(rest[1]), int(rest[2])]
            elif name == "delay":
                self.delays[int(rest[0])] = [float(rest[1]), int(rest[2])]
            elif name == "refuse":
                self.drives[int(rest[0])].refuse = True
            elif name == "stop_server":
                asyncio.ensure_future(self.stop_server())
            elif name == "restart_server":
                asyncio.ensure_future(self.restart_server(float(rest[0])))
            elif name == "query":
                d = self.drives[int(rest[0])]
                word, pos = d.status()
                emit(f"STATE {d.unit} moving={1 if word & MOVING else 0} position={int(round(pos))} "
                     f"target={d.target} fault={d.fault}")
            elif name == "clear":
                self.exceptions.clear()
                self.delays.clear()
                for d in self.drives.values():
                    d.stuck = d.refuse = False
            else:
                emit(f"ERROR unknown command {line}")
                return
            emit(f"OK {line}")
        except (IndexError, KeyError, ValueError) as e:
            emit(f"ERROR {line}: {e}")

    async def main(self):
        self.loop = asyncio.get_running_loop()
        await self.start_server()
        emit(f"LISTENING {self.port}")
        done = asyncio.Event()

        def read_stdin():
            for line in sys.stdin:
                self.loop.call_soon_threadsafe(self.run_command, line.strip())
            self.loop.call_soon_threadsafe(done.set)  # stdin closed: the test is gone

        threading.Thread(target=read_stdin, daemon=True).start()
        await done.wait()
        await self.stop_server()


def main():
    logging.disable(logging.CRITICAL)  # pymodbus logs every injected fault as an error; the test judges them
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--units", default="1,2")
    parser.add_argument("--word-order", default="high-first", choices=["high-first", "low-first"])
    parser.add_argument("--register-base", type=int, default=0)
    parser.add_argument("--home-time-s", type=float, default=0.05)
    parser.add_argument("--port", type=int, default=0)
    asyncio.run(Peer(parser.parse_args()).main())


if __name__ == "__main__":
    main()
