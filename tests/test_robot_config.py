"""robot.toml: every table checked on load, errors naming the file, the key and the value."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from heapgrasp.robot.config import RobotConfig, Workspace
from heapgrasp.robot.errors import RobotConfigError, SafetyError
from heapgrasp.robot.safety import check_inside, check_path


def test_defaults_load_and_the_gripper_uses_the_arm_host(tmp_path: Path) -> None:
    f = tmp_path / "robot.toml"
    f.write_text('[arm]\nhost = "10.0.0.2"\n[camera]\nwidth = 640\nheight = 480\n')
    cfg = RobotConfig.load(f)
    assert cfg.gripper_host == "10.0.0.2"
    assert cfg.camera.width == 640 and cfg.source == str(f)
    assert not cfg.calibration.done


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[arm]\nhots = 'x'\n", "unknown key 'hots'"),
        ("[arms]\nhost = 'x'\n", "unknown table or key 'arms'"),
        ("[arm]\nservo_rate = 'fast'\n", "servo_rate must be of type float"),
        ("[arm]\ntcp = [0, 0, 0.2]\n", "tcp must be 6 finite numbers"),
        ("[workspace]\nmin = [0, 0, 0]\nmax = [1, -1, 1]\n", "must be below max"),
        ("[limits]\ntool_speed = 3.0\n", "above 1 m/s"),
        ("[limits]\njoint_speed = -1\n", "joint_speed must be a number > 0"),
        ("[camera]\nwidth = 333\n", "333x240 is not a colour mode"),
        ("[camera]\nfps = 25\n", "fps must be 6, 15, 30 or 60"),
        ("[gripper]\nforce = 300\n", "force must be an integer in"),
        ("[calibration]\ncam2tcp = [[1, 0], [0, 1]]\n", "cam2tcp must be a finite 4x4"),
        (
            "[calibration]\ncam2tcp = [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\n",
            "rigid transform",
        ),
        ("arm = 3\n", r"\[arm\] must be a table"),
        ("[arm\n", "not valid TOML"),
        ("[gripper]\nport = true\n", "port must be of type int, got True"),
        ("[camera]\nwidth = false\n", "width must be of type int, got False"),
    ],
)
def test_bad_values_are_named(tmp_path: Path, text: str, message: str) -> None:
    f = tmp_path / "robot.toml"
    f.write_text(text)
    with pytest.raises(RobotConfigError, match=message) as err:
        RobotConfig.load(f)
    assert str(f) in str(err.value)


def test_a_missing_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(RobotConfigError, match="not found"):
        RobotConfig.load(tmp_path / "nope.toml")
    binary = tmp_path / "robot.toml"
    binary.write_bytes(bytes(range(256)))
    with pytest.raises(RobotConfigError, match="not a text file") as err:
        RobotConfig.load(binary)
    assert str(binary) in str(err.value)
    with pytest.raises(RobotConfigError, match="cannot be read") as err:
        RobotConfig.load(tmp_path)  # a folder
    assert str(tmp_path) in str(err.value)


def test_calibration_and_method_are_kept() -> None:
    m = np.eye(4)
    m[:3, 3] = (0.1, 0.0, 0.05)
    cfg = RobotConfig.from_mapping(
        {
            "calibration": {
                "cam2tcp": m.tolist(),
                "world2base": np.eye(4).tolist(),
                "method": "park",
            },
            "method": {"L": 2},
        }
    )
    assert cfg.calibration.done and np.allclose(cfg.calibration.cam2tcp, m)
    assert cfg.calibration.report == {"method": "park"}
    assert cfg.method == {"L": 2}


def test_the_box_and_the_caps() -> None:
    box = Workspace((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (0.5, 0.5, 0.5))
    check_inside(box, [[0.5, 0.5, 0.5], [1.0, 1.0, 1.0]], "the TCP")
    with pytest.raises(SafetyError, match=r"sample 1 of 2"):
        check_inside(box, [[0.5, 0.5, 0.5], [1.0, 1.2, 1.0]], "the TCP")
    from heapgrasp.robot.config import Limits

    poses = np.repeat(np.eye(4)[None], 3, axis=0)
    poses[:, 0, 3] = [0.1, 0.2, 0.3]
    check_path(box, Limits(), [0.0, 1.0, 2.0], poses, np.eye(4))
    with pytest.raises(SafetyError, match="tool_speed"):
        check_path(box, Limits(tool_speed=0.05), [0.0, 1.0, 2.0], poses, np.eye(4))
    with pytest.raises(SafetyError, match="increasing"):
        check_path(box, Limits(), [0.0, 0.0, 2.0], poses, np.eye(4))
