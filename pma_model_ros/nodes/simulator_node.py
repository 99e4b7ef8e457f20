"""simulator_node: a pneumatic muscle whose static force is its measured force map.

Publishes, at ``rate``, ``pressure`` (sensor_msgs/FluidPressure, absolute Pa),
``muscle_state`` (sensor_msgs/JointState: position = length [m], velocity = length
rate [m/s], effort = measured tension [N]) and ``force`` (geometry_msgs/WrenchStamped,
force.x = measured tension [N]), all with the same stamp.  The pressure follows
``pressure_command`` (FluidPressure, absolute Pa) with first-order dynamics.
Parameters are read at start-up.
"""
from __future__ import annotations

import math
import sys

from geometry_msgs.msg import WrenchStamped
import numpy as np
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import FluidPressure, JointState

from ..core.force_map import MAPPED_MUSCLES, shipped_force_map
from ..core.ground_truth import GroundTruth
from .ros_time import now_seconds
from .startup import StartupError, run

TRAJECTORIES = ("constant", "sine", "sweep")
#: name: (default, description, (min, max) or None)
PARAMETERS = {
    "muscle": ("DMSP-10-250", f"shipped muscle whose measured map is the truth: {', '.join(MAPPED_MUSCLES)}", None),
    "rate": (100.0, "publishing rate [Hz]", (1.0, 1000.0)),
    "ambient_pressure": (101325.0, "ambient pressure [Pa absolute]", (0.0, 2e5)),
    "joint_name": ("", "JointState entry name (empty: the muscle name)", None),
    "noise.pressure_std": (0.0, "standard deviation of the published pressure [Pa]", (0.0, 1e5)),
    "noise.length_std": (0.0, "standard deviation of the published length [m]", (0.0, 0.01)),
    "noise.force_std": (0.0, "standard deviation of the published force [N]", (0.0, 1e3)),
    "seed": (0, "seed of the noise generator", None),
    "hysteresis_gap": (0.0, "half-gap of a hysteresis [N]: + when lengthening, - when shortening, faded out "
                            "below this force (Sárosi's DMSP-10-100 branches differ by about 10 % of force)",
                       (0.0, 1e4)),
    "pressure_time_constant": (0.05, "first-order time constant toward the commanded pressure [s]", (0.0, 60.0)),
    "initial_pressure": (0.0, "gauge pressure [Pa] before any pressure_command ('constant' and 'sine')",
                         (0.0, 5e6)),
    "trajectory": ("sweep", f"length trajectory: {', '.join(TRAJECTORIES)}; 'sweep' also sweeps the pressure "
                            "until a pressure_command arrives", None),
    "length": (0.23, "length for the 'constant' trajectory [m]", (0.0, 10.0)),
    "length_min": (0.2, "lower length of the 'sine' trajectory [m]", (0.0, 10.0)),
    "length_max": (0.25, "upper length of the 'sine' trajectory [m]", (0.0, 10.0)),
    "period": (4.0, "period of the 'sine' and of the 'sweep' length triangle [s]", (0.01, 1e4)),
    "sweep_period": (20.0, "period of the 'sweep' pressure triangle over the map's pressures [s]", (0.01, 1e4)),
}


def triangle(t: float, period: float) -> tuple[float, float]:
    """Triangle wave 0 -> 1 -> 0 over ``period`` [s]: (value, slope [1/s])."""
    phase = (t / period) % 1.0
    return (2 * phase, 2 / period) if phase < 0.5 else (2 - 2 * phase, -2 / period)


class SimulatorNode(Node):
    """Publishes a simulated muscle at a fixed rate."""

    def __init__(self) -> None:
        super().__init__("simulator_node")
        try:
            for name, (default, text, limits) in PARAMETERS.items():
                ranges = [FloatingPointRange(from_value=limits[0], to_value=limits[1])] if limits else []
                self.declare_parameter(name, default, ParameterDescriptor(description=text,
                                                                          floating_point_range=ranges))
            p = {name: self.get_parameter(name).value for name in PARAMETERS}
            if p["trajectory"] not in TRAJECTORIES:
                raise ValueError(f"parameter 'trajectory' must be one of {TRAJECTORIES}, got {p['trajectory']!r}")
            if p["trajectory"] == "sine" and not p["length_min"] < p["length_max"]:
                raise ValueError("parameters 'length_min' < 'length_max' needed for 'sine'")
            self._truth = GroundTruth(shipped_force_map(p["muscle"]))
        except (ParameterException, ValueError) as err:
            raise StartupError(str(err)) from None
        self._p = p
        self._joint = p["joint_name"] or p["muscle"]
        self._rng = np.random.default_rng(p["seed"])
        self._pressure = p["initial_pressure"]  # gauge [Pa]
        self._command: float | None = None      # commanded gauge pressure [Pa]
        self._start = self._last = now_seconds(self)

        self._pressure_pub = self.create_publisher(FluidPressure, "pressure", qos_profile_sensor_data)
        self._state_pub = self.create_publisher(JointState, "muscle_state", qos_profile_sensor_data)
        self._force_pub = self.create_publisher(WrenchStamped, "force", qos_profile_sensor_data)
        self.create_subscription(FluidPressure, "pressure_command", self._on_command, 10)
        self.create_timer(1.0 / p["rate"], self._tick)
        self.get_logger().info(f"simulating {p['muscle']} ({p['trajectory']}) at {p['rate']:g} Hz")

    def _on_command(self, msg: FluidPressure) -> None:
        if math.isfinite(msg.fluid_pressure):
            self._command = msg.fluid_pressure - self._p["ambient_pressure"]

    def _length(self, t: float) -> tuple[float, float]:
        """Length [m] and its rate [m/s] at time ``t`` [s] after start."""
        p = self._p
        if p["trajectory"] == "constant":
            return p["length"], 0.0
        if p["trajectory"] == "sine":
            mid, amp, w = (p["length_max"] + p["length_min"]) / 2, (p["length_max"] - p["length_min"]) / 2, \
                2 * math.pi / p["period"]
            return mid + amp * math.sin(w * t), amp * w * math.cos(w * t)
        low, high = self._truth.lengths[0], self._truth.lengths[-1]
        value, slope = triangle(t, p["period"])
        return low + (high - low) * value, (high - low) * slope

    def _target(self, t: float) -> float:
        """Gauge pressure [Pa] the muscle is driven toward at time ``t`` [s]."""
        if self._command is not None:
            return self._command
        if self._p["trajectory"] == "sweep":
            low, high = self._truth.pressures[0], self._truth.pressures[-1]
            return low + (high - low) * triangle(t, self._p["sweep_period"])[0]
        return self._p["initial_pressure"]

    def _tick(self) -> None:
        p, now = self._p, now_seconds(self)
        dt, self._last = max(now - self._last, 0.0), now
        t = now - self._start
        tau = p["pressure_time_constant"]
        self._pressure += (self._target(t) - self._pressure) * (1.0 - math.exp(-dt / tau) if tau > 0 else 1.0)
        length, rate = self._length(t)
        force = float(self._truth.force(self._pressure, length))
        force += math.copysign(min(p["hysteresis_gap"], force), rate) if rate else 0.0
        noise = self._rng.normal(size=3) * [p["noise.pressure_std"], p["noise.length_std"], p["noise.force_std"]]
        measured = force + noise[2]
        stamp = self.get_clock().now().to_msg()

        pressure = FluidPressure(fluid_pressure=self._pressure + p["ambient_pressure"] + noise[0])
        state = JointState(name=[self._joint], position=[length + noise[1]], velocity=[rate], effort=[measured])
        wrench = WrenchStamped()
        wrench.wrench.force.x = measured
        for msg in (pressure, state, wrench):
            msg.header.stamp = stamp
            msg.header.frame_id = self._joint
        self._pressure_pub.publish(pressure)
        self._state_pub.publish(state)
        self._force_pub.publish(wrench)


def main(args: list[str] | None = None) -> int:
    return run("simulator_node", SimulatorNode, args)


if __name__ == "__main__":
    sys.exit(main())
