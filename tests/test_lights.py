"""The light protocol through pyserial over a real pty, against the simulated board."""
import time

import pytest

from hardware.lights import (LightCommandError, LightController, LightLinkError, LightProtocolError, LightState,
                             LightTimeout, parse_status)
from hardware.sim_lights import BoardState, SimulatedLightBoard, handle


@pytest.fixture
def board():
    with SimulatedLightBoard() as b:
        yield b


@pytest.fixture
def lights(board):
    with LightController(board.port, timeout=0.3, retries=2) as lc:
        yield lc


def test_normal_session(board, lights):
    assert lights.identify().startswith("HAIRDIGI-LIGHTS 1 ")
    lights.set_light(0, True, 200)
    lights.set_light(2, True)
    assert lights.status() == (LightState(True, 200), LightState(False, 255), LightState(True, 255))
    assert board.state.levels() == pytest.approx((200 / 255, 0.0, 1.0))
    lights.all_off()
    assert not any(s.on for s in lights.status())
    assert board.received[:3] == ["ID?", "L0 I 200", "L0 ON"]


def test_lost_garbage_and_partial_replies_are_retried(board, lights):
    for fault in ("drop", "garbage", "partial", "slow"):
        board.inject(fault)
        lights.set_light(1, True)
        assert lights.status()[1].on
    # a retried command is sent again, and is harmless because every command is idempotent
    assert board.received.count("L1 ON") >= 5


def test_timeout_after_the_retries(board, lights):
    board.inject("drop", "drop", "drop")
    t0 = time.monotonic()
    with pytest.raises(LightTimeout, match=r"no reply to 'STATUS\?'.*after 3 tries"):
        lights.status()
    assert time.monotonic() - t0 < 3.0


def test_garbage_every_time_is_a_protocol_error(board, lights):
    board.inject("garbage", "garbage", "garbage")
    with pytest.raises(LightProtocolError, match="garbage reply"):
        lights.status()


def test_unplug_mid_command_then_replug(board, lights):
    lights.set_light(0, True)
    board.inject("unplug")
    with pytest.raises(LightLinkError, match="check the USB cable"):
        lights.set_light(1, True)
    board.plug()                 # the board comes back under the same by-id path
    lights.set_light(1, True)    # and the controller reconnects by itself
    assert lights.status()[1].on and lights.connected


def test_board_refusals_are_clear(board, lights):
    with pytest.raises(LightCommandError, match="E1 unknown command"):
        lights.command("BLINK")
    with pytest.raises(ValueError, match="light 5 does not exist"):
        lights.set_light(5, True)
    with pytest.raises(ValueError, match="0-255"):
        lights.set_light(0, intensity=300)


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
