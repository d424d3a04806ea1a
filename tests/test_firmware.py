"""The real firmware (hairdigi_lights.ino, built for an Arduino Uno, run in the simavr AVR emulator) against
PROTOCOL.md and against the Python simulator, byte for byte through raw pyserial on both ptys.

The host (hardware/lights.py) refuses to send most of these lines; a careless or hostile host, or line
noise, may not, so the boards must agree on them. tests/test_lights.py runs the host on both boards.
"""
import os
import re
import statistics
import time

import pytest
import serial

from hairdigi.hardware.sim_lights import BoardState, EmulatedFirmwareBoard, SimulatedLightBoard, handle

UNO_FLASH, UNO_RAM = 32256, 2048  # bytes the Uno's bootloader leaves for a sketch; SRAM
E1, E2, E3, E4 = "ERR E1 unknown command", "ERR E2 no such light", "ERR E3 value out of range", "ERR E4 line too long"

# (line sent, without its "\n"; the reply PROTOCOL.md asks for)
CASES = [
    (b"L10 ON", E2), (b"L-1 ON", E2), (b"L3 ON", E2), (b"L01 ON", E2), (b"Lx ON", E2), (b"L ON", E2),
    (b"LAMP ON", E2), (b"L9 BLINK", E2),
    (b"L0 I +5", E3), (b"L0 I -0", E3), (b"L0 I 256", E3), (b"L0 I 1e2", E3), (b"L0 I 5 ", E3), (b"L0 I  5", E3),
    (b"L0 I ", E3), (b"L0 I 0x10", E3), (b"L0 I 99999999999999999999", E3),
    (b"L0 \rON", E1), (b"\rID?", E1), (b"ID?\r\r", E1), (b"L0 I 5\r0", E1), (b"ID?\x00", E1), (b"ID?\x00garbage", E1),
    (b"L0\tON", E1), (b"L0 \xd6N", E1), (b"\xff", E1), (b"", E1), (b" ID?", E1), (b"ID? ", E1), (b"id?", E1),
    (b"L0 on", E1), (b"L0 ON ", E1), (b"L0  ON", E1), (b"L0 I", E1), (b"L0", E1), (b"ALL  OFF", E1),
    (b"X" * 32, E1), (b"X" * 33, E4), (b"X" * 32 + b"\r", E1), (b"X" * 33 + b"\r", E4), (b"\xff" * 40, E4),
    (b"X" * 300, E4),
    (b"L0 I 007", "OK"), (b"L0 I 0000000000000000000000255", "OK"), (b"L1 I 0", "OK"), (b"L2 ON\r", "OK"),
    (b"L2 OFF", "OK"), (b"L1 ON", "OK"), (b"ALL OFF\r", "OK"),
]




@pytest.fixture(scope="module")
def ports(avr_build):
    """Raw serial ports on both boards: {"python-sim": port, "avr-firmware": port}."""
    with SimulatedLightBoard() as sim, EmulatedFirmwareBoard(avr_build) as avr:
        with serial.Serial(sim.port, 115200, timeout=1.0) as s, serial.Serial(avr.port, 115200, timeout=1.0) as a:
            yield {"python-sim": s, "avr-firmware": a}


def exchange(port: serial.Serial, data: bytes, n_replies: int = 1) -> list[str]:
    """Write ``data`` and read ``n_replies`` lines (each must come whole, within the port's timeout)."""
    port.reset_input_buffer()
    port.write(data)
    replies = [port.readline() for _ in range(n_replies)]
    assert all(r.endswith(b"\n") for r in replies), f"{data!r}: no whole reply ({replies!r})"
    return [r.decode("ascii").rstrip("\n") for r in replies]


def test_firmware_fits_an_uno(avr_build):
    size = (avr_build / "size.txt").read_text()
    flash = int(re.search(r"Program:\s+(\d+) bytes", size).group(1))
    ram = int(re.search(r"Data:\s+(\d+) bytes", size).group(1))
    print(f"firmware: {flash} bytes of flash ({flash / UNO_FLASH:.0%}), {ram} bytes of RAM ({ram / UNO_RAM:.0%})")
    assert flash < UNO_FLASH / 2 and ram < UNO_RAM / 2  # room for the stack and for what comes next


@pytest.mark.parametrize("line, reply", CASES, ids=[repr(line)[2:-1][:24] for line, _ in CASES])
def test_both_boards_follow_the_protocol(ports, line, reply):
    assert handle(line.decode("latin-1"), BoardState()) == reply
    for name, port in ports.items():
        assert exchange(port, line + b"\n") == [reply], name
    # and a refused line changed nothing: both boards are in the same state
    assert exchange(ports["python-sim"], b"STATUS?\n") == exchange(ports["avr-firmware"], b"STATUS?\n")


def test_both_boards_carry_out_commands_alike(ports):
    script = [b"L0 I 10", b"L1 I 020", b"L2 I 255", b"L0 ON", b"L2 ON", b"L1 ON", b"L1 OFF", b"STATUS?"]
    replies = {name: [exchange(port, line + b"\n")[0] for line in script] for name, port in ports.items()}
    assert replies["avr-firmware"] == replies["python-sim"] == ["OK"] * 7 + ["OK 1:10 0:20 1:255"]


def test_pipelined_commands_are_answered_in_order(ports):
    """More bytes at once than the AVR's 64-byte receive buffers hold: none lost, one reply a line."""
    lines = [b"L0 I 1", b"L0 I 2", b"X" * 40, b"L5 ON", b"L0 I 3", b"STATUS?"] * 4
    expected = ["OK", "OK", E4, E2, "OK", "OK 0:3 0:255 0:255"] * 4
    for name, port in ports.items():
        assert exchange(port, b"ALL OFF\nL1 I 255\nL2 I 255\n", 3) == ["OK"] * 3, name
        assert exchange(port, b"\n".join(lines) + b"\n", len(lines)) == expected, name


def test_a_line_may_arrive_in_pieces(ports):
    for name, port in ports.items():
        port.reset_input_buffer()
        for piece in (b"STA", b"TUS", b"?", b"\r\n"):
            port.write(piece)
            time.sleep(0.02)
        assert port.readline().startswith(b"OK "), name


def test_firmware_identifies_itself_and_answers_in_time(ports):
    port = ports["avr-firmware"]
    assert re.fullmatch(r"OK HAIRDIGI-LIGHTS 1 fw-\S+ \S+", exchange(port, b"ID?\n")[0])
    latencies = []
    for _ in range(30):
        t0 = time.monotonic()
        exchange(port, b"STATUS?\n")
        latencies.append(time.monotonic() - t0)
    print(f"firmware STATUS? round trip: median {statistics.median(latencies) * 1e3:.1f} ms, "
          f"max {max(latencies) * 1e3:.1f} ms")
    assert statistics.median(latencies) < 0.1  # PROTOCOL.md: within 100 ms


def test_emulator_removes_its_port_when_stopped(avr_build, tmp_path):
    board = EmulatedFirmwareBoard(avr_build, tmp_path)
    assert os.path.realpath(board.port).startswith("/dev/pts/")
    board.close()
    assert not os.path.lexists(board.port)
