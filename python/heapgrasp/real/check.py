"""``heapgrasp robot check``: connect to each device, report what it sees, move nothing.

Every item is checked on its own and reported (``ok`` and a detail), so one missing
device does not hide the state of the others: the configuration and the loop's
settings, the calibration, the segmentation network, the camera (its streams, one
frame, the frame rate measured over a second), the gripper (its registers, without
activating it) and the arm (robot and safety modes, the TCP in the workspace frame and
whether it is inside the box).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from heapgrasp.loop.methods import method_of
from heapgrasp.real.stages import load, make_segmenter, open_networks
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.hardware import Drivers, camera_settings
from heapgrasp.robot.ur import pose_from_rtde

__all__ = ["check"]


def _item(name: str, fn: Callable[[], str]) -> dict[str, Any]:
    try:
        return {"item": name, "ok": True, "detail": fn()}
    except Exception as exc:  # every failure is reported, not raised
        return {"item": name, "ok": False, "detail": f"{type(exc).__name__}: {exc}"}


def check(config_path: str | Path, *, drivers: Drivers | None = None) -> list[dict[str, Any]]:
    """The state of every device and setting (see the module docstring); raises only
    where ``robot.toml`` itself cannot be read."""
    robot = RobotConfig.load(config_path)
    d = drivers or Drivers()
    items: list[dict[str, Any]] = []
    loaded: dict[str, Any] = {}

    def settings() -> str:
        _, cfg = load(config_path, simulated=d.scene is not None)
        loaded["cfg"] = cfg
        grasps = cfg.grasp_planner_in_use
        return f"method {cfg.method}, view planner {cfg.view_planner}, grasps {grasps}"

    items.append(_item("settings", settings))

    def calibration() -> str:
        cal = robot.calibration
        if not cal.done:
            raise ValueError("not calibrated: run `heapgrasp robot calibrate`")
        rep = cal.report
        return (
            f"method {rep.get('method', '?')}, residual max {rep.get('residual_mm_max', '?')} mm,"
            f" on {rep.get('date', '?')}"
        )

    items.append(_item("calibration", calibration))

    def network() -> str:
        cfg = loaded.get("cfg")
        if cfg is None:
            raise ValueError("the settings did not load")
        seg = make_segmenter(cfg, d.scene)
        if seg is None:
            return "none needed (depth baseline)"
        if method_of(cfg).true_silhouettes:
            return "none needed (the rehearsal's exact silhouettes)"
        return f"{cfg.seg_weights} opens"

    items.append(_item("segmentation network", network))

    def planners() -> str:
        cfg = loaded.get("cfg")
        if cfg is None:
            raise ValueError("the settings did not load")
        nets = open_networks(cfg, d.hand, d.scene)
        view = "none (fixed views)" if nets.view_scorer is None else "view network opens"
        critic = "no critic" if nets.critic is None else "critic opens"
        return f"{type(nets.grasp_planner).__name__}; {view}; {critic}"

    items.append(_item("grasp and view planners", planners))

    def camera() -> str:
        cam = d.camera(camera_settings(robot))
        cam.start()
        try:
            first = cam.wait(robot.camera.timeout)
            t0 = d.clock()
            n = 0
            while d.clock() - t0 < 1.0:
                n += len(cam.poll())
                d.sleep(0.01)
            info = cam.describe() if hasattr(cam, "describe") else {}
            spec = cam.spec
            return (
                f"{info.get('name', 'camera')} {info.get('serial', '')}: {spec.width}x{spec.height}"
                f" fx {spec.fx:.1f}, {n} frames in 1 s, mean brightness "
                f"{float(np.mean(first.rgb)):.0f}/255"
                + ("" if first.depth is None else f", depth median {np.median(first.depth):.3f} m")
            )
        finally:
            cam.stop()

    items.append(_item("camera", camera))

    def gripper() -> str:
        if d.scene is None:
            robot.require_hosts(("gripper",))
        g = d.gripper(robot)
        g.connect()
        try:
            status = g.status()
            active = "activated" if status.get("STA") == 3 else "not activated"
            where = (
                "rehearsal" if d.scene is not None else f"{robot.gripper_host}:{robot.gripper.port}"
            )
            return f"{where} {active}, registers {status}"
        finally:
            g.disconnect()

    items.append(_item("gripper", gripper))

    def arm() -> str:
        if d.scene is None:
            robot.require_hosts(("arm",))
        control, receive = d.arm(robot.arm.host, robot.arm.tcp)
        try:
            tcp = pose_from_rtde(receive.getActualTCPPose())
            modes = f"robot mode {receive.getRobotMode()}, safety mode {receive.getSafetyMode()}"
            if receive.isProtectiveStopped():
                raise ValueError(f"protective stop ({modes})")
            where = f"TCP {np.round(tcp[:3, 3], 3).tolist()} m (base)"
            cal = robot.calibration
            if cal.world2base is not None:
                world = np.linalg.inv(cal.world2base) @ tcp
                inside = bool(robot.workspace.contains(world[:3, 3]).all())
                where = (
                    f"TCP {np.round(world[:3, 3], 3).tolist()} m (workspace), "
                    f"{'inside' if inside else 'OUTSIDE'} the box"
                )
            host = "rehearsal" if d.scene is not None else robot.arm.host
            return f"{host}: {modes}, {where}"
        finally:
            control.disconnect()
            receive.disconnect()

    items.append(_item("arm", arm))
    return items
