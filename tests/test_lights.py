"""The light protocol through pyserial over a real pty: against the Python simulator and the real firmware.

``board`` runs each protocol test twice: on ``SimulatedLightBoard`` (Python) and on
``EmulatedFirmwareBoard`` (hairdigi_lights.ino built for an Uno, run in the simavr AVR emulator).
Fault injection (lost, garbled, slow replies; an unplug mid-command) only the Python simulator can do.
"""
import time
from fractions import Fraction

import numpy as np
import pytest

from hairdigi.hardware.lights import (LightArgumentError, LightCommandError, LightController, LightError, LightLinkError,
                                      LightProtocolError, LightState, LightTimeout, N_LIGHTS, parse_status)
from hairdigi.hardware.sim_lights import BoardState, SimulatedLightBoard, handle
from deadlines import within


@pytest.fixture
def lights(board):
    with LightController(board.port, timeout=0.3, retries=2) as lc:
        yield lc


@pytest.fixture
def sim():
    """The Python simulator alone, for fault injection."""
    with SimulatedLightBoard() as b:
        yield b


@pytest.fixture
def sim_lights(sim):
    with LightController(sim.port, timeout=0.3, retries=2) as lc:
        yield lc


# -- the protocol, on both boards -------------------------------------------------------------------
def test_normal_session(board, lights):
    assert lights.identify().startswith("HAIRDIGI-LIGHTS 1 ")
    lights.set_light(0, True, 200)
    lights.set_light(2, True)
    assert lights.status() == (LightState(True, 200), LightState(False, 255), LightState(True, 255))
    if isinstance(board, SimulatedLightBoard):
        assert board.state.levels() == pytest.approx((200 / 255, 0.0, 1.0))
    lights.all_off()
    assert not any(s.on for s in lights.status())
    assert board.received[:3] == ["ID?", "L0 I 200", "L0 ON"]


def test_board_refusals_are_clear(board, lights):
    with pytest.raises(LightCommandError, match="E1 unknown command"):
        lights.command("BLINK")
    with pytest.raises(LightCommandError, match="E2 no such light"):
        lights.command("L10 ON")
    with pytest.raises(LightCommandError, match="E3 value out of range"):
        lights.command("L0 I -0")
    with pytest.raises(LightArgumentError, match="at most 32"):   # the firmware's E4 limit, kept by the host
        lights.command("L0 I " + "0" * 40)


def test_a_refused_command_is_sent_once(board, lights):
    for command in ("BLINK", "L3 ON", "L0 I 256", "X" * 32):
        with pytest.raises(LightCommandError):
            lights.command(command)
    assert board.received == ["BLINK", "L3 ON", "L0 I 256", "X" * 32]


def test_driver_fault_is_refused_and_not_retried(board, lights):
    board.set_fault(1, True)
    with pytest.raises(LightCommandError, match="E5 driver fault"):
        lights.set_light(1, True)
    lights.set_light(1, False)  # switching off still works
    board.set_fault(1, False)
    lights.set_light(1, True)
    assert [s.on for s in lights.status()] == [False, True, False]
    assert board.received == ["L1 ON", "L1 OFF", "L1 ON", "STATUS?"]


@pytest.mark.parametrize("command", ["L1 ON\nL2 ON", "L1 ON\r", "L1 ON\r\nL2 ON", "\n", "L1 ÖN", "L1 ON\x00",
                                     "L1\tON", "L1 ON\u2028", "ID?\x85"])
def test_line_breaks_and_non_ascii_are_never_sent(board, lights, command):
    before = lights.status()
    n_received = len(board.received)
    with pytest.raises(LightArgumentError, match="line break|printable ASCII"):
        lights.command(command)
    assert len(board.received) == n_received  # nothing was written
    assert lights.status() == before


def test_unplugged_between_commands_then_replugged(board, lights):
    lights.set_light(0, True)
    board.unplug()
    with pytest.raises(LightLinkError, match="check the USB cable"):
        lights.status()
    board.plug()                  # the board comes back (the firmware boots afresh)
    lights.set_light(1, True)     # and the controller reconnects by itself
    assert lights.status()[1].on and lights.connected


# -- the host's own checks ------------------------------------------------------------------------
@pytest.mark.parametrize("index", [-1, N_LIGHTS, 10, 1.0, "1", True, False, None, 1 + 0j])
def test_light_index_must_be_an_int_in_range(sim, sim_lights, index):
    with pytest.raises(LightArgumentError, match=r"light index must be an int from 0 to 2"):
        sim_lights.set_light(index, True)
    assert sim.received == []


@pytest.mark.parametrize("intensity", [-1, 256, 255.5, -0.01, float("nan"), float("inf"), "200", True, b"\x05", 1j])
def test_intensity_must_be_a_number_in_range(sim, sim_lights, intensity):
    with pytest.raises(LightArgumentError, match=r"intensity must be a number from 0 to 255"):
        sim_lights.set_light(0, True, intensity)
    assert sim.received == []


@pytest.mark.parametrize("on", ["off", "", 1, 0, np.True_])
def test_on_must_be_a_bool(sim, sim_lights, on):
    with pytest.raises(LightArgumentError, match="on must be True, False or None"):
        sim_lights.set_light(0, on, 100)
    assert sim.received == []


def test_accepted_argument_types(sim, sim_lights):
    sim_lights.set_light(np.int64(2), True, np.float32(99.6))
    sim_lights.set_light(0, False, Fraction(1, 2))
    sim_lights.set_light(1, intensity=255.0)
    assert sim.received == ["L2 I 100", "L2 ON", "L0 I 0", "L0 OFF", "L1 I 255"]


def test_argument_errors_are_light_errors_and_value_errors():
    assert issubclass(LightArgumentError, LightError) and issubclass(LightArgumentError, ValueError)


# -- fault injection, on the Python simulator only --------------------------------------------------
def test_lost_garbage_and_partial_replies_are_retried(sim, sim_lights):
    for fault in ("drop", "garbage", "partial", "slow"):
        sim.inject(fault)
        sim_lights.set_light(1, True)
        assert sim_lights.status()[1].on
    # a retried command is sent again, and is harmless because every command is idempotent
    assert sim.received.count("L1 ON") >= 5


def test_a_refusal_after_a_lost_reply_is_not_retried(sim, sim_lights):
    sim.inject("drop")
    with pytest.raises(LightCommandError, match="E1"):
        sim_lights.command("BLINK")
    assert sim.received == ["BLINK", "BLINK"]  # the lost reply is retried, the refusal is not


def test_timeout_after_the_retries(sim, sim_lights):
    sim.inject("drop", "drop", "drop")
    t0 = time.monotonic()
    with pytest.raises(LightTimeout, match=r"no reply to 'STATUS\?'.*after 3 tries"):
        sim_lights.status()
    assert time.monotonic() - t0 < within(3.0)


def test_garbage_every_time_is_a_protocol_error(sim, sim_lights):
    sim.inject("garbage", "garbage", "garbage")
    with pytest.raises(LightProtocolError, match="garbage reply"):
        sim_lights.status()


def test_unplug_mid_command_then_replug(sim, sim_lights):
    sim_lights.set_light(0, True)
    sim.inject("unplug")
    with pytest.raises(LightLinkError, match="check the USB cable"):
        sim_lights.set_light(1, True)
    sim.plug()                     # the board comes back under the same by-id path
    sim_lights.set_light(1, True)  # and the controller reconnects by itself
    assert sim_lights.status()[1].on and sim_lights.connected


# -- without a port -------------------------------------------------------------------------------
def test_open_missing_port_names_the_fix(tmp_path):
    with pytest.raises(LightLinkError, match="check the USB cable"):
        LightController(str(tmp_path / "ttyNONE"))


def test_protocol_handler_edge_cases():
    s = BoardState()
    assert handle("L3 ON", s) == "ERR E2 no such light"
    assert handle("L0 I 256", s) == "ERR E3 value out of range"
    assert handle("L0 I x", s) == "ERR E3 value out of range"
    assert handle("X" * 40, s) == "ERR E4 line too long"
    assert handle("STATUS?", s) == "OK 0:255 0:255 0:255"
    with pytest.raises(LightProtocolError):
        parse_status("OK 1:2 3")
