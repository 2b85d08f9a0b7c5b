"""IMU handling for the replay: extrinsic rotation into the sensor frame, initial attitude
(6-axis: roll/pitch from the averaged accelerometer; 9-axis: the IMU's orientation), gyro
orientation track for deskew, and gtsam preintegration for the motion prior between sweeps."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from mrnc_eval.data import ImuSeries


@dataclass(frozen=True)
class ImuTrack:
    """IMU samples rotated into the LiDAR sensor frame, with an integrated orientation track."""

    stamps: np.ndarray
    acc: np.ndarray  # (N, 3) sensor frame, m/s^2
    gyro: np.ndarray  # (N, 3) sensor frame, rad/s
    rot: Rotation  # orientation of the sensor at each stamp relative to the first sample (gyro only)

    def rotation_between(self, t0: float, t1: np.ndarray) -> Rotation:
        """Rotation of the sensor at times t1 relative to t0 (gyro integration, interpolated)."""
        return self._at(np.atleast_1d(t0))[0].inv() * self._at(np.atleast_1d(t1))

    def _at(self, t: np.ndarray) -> Rotation:
        from scipy.spatial.transform import Slerp

        tc = np.clip(t, self.stamps[0], self.stamps[-1])
        return Slerp(self.stamps, self.rot)(tc)

    def covers(self, t0: float, t1: float) -> bool:
        return self.stamps.size > 1 and self.stamps[0] <= t0 and self.stamps[-1] >= t1


def imu_track(imu: ImuSeries, sensor_to_imu_rot: np.ndarray, gyro_bias: np.ndarray | None = None) -> ImuTrack:
    r = sensor_to_imu_rot  # rotates IMU-frame vectors into the sensor frame
    acc = imu.acc @ r.T
    gyro = (imu.gyro - (0 if gyro_bias is None else gyro_bias)) @ r.T
    dt = np.diff(imu.stamps)
    steps = Rotation.from_rotvec(gyro[:-1] * dt[:, None])
    quats = [Rotation.identity()]
    # sequential composition is the integration itself (N small: 100 Hz)
    cur = Rotation.identity()
    for s in steps:
        cur = cur * s
        quats.append(cur)
    return ImuTrack(imu.stamps, acc, gyro, Rotation.concatenate(quats))


def initial_attitude(imu: ImuSeries, sensor_to_imu_rot: np.ndarray, window_s: float = 0.5) -> Rotation:
    """Roll and pitch (yaw = 0) of the sensor from the mean specific force of the first window,
    or the IMU's own orientation for a 9-axis IMU."""
    if imu.orientation_xyzw is not None:
        q = Rotation.from_quat(imu.orientation_xyzw[0]) * Rotation.from_matrix(sensor_to_imu_rot).inv()
        r, p, _ = q.as_euler("xyz")
        return Rotation.from_euler("xyz", [r, p, 0.0])
    sel = imu.stamps <= imu.stamps[0] + window_s
    f = (imu.acc[sel] @ sensor_to_imu_rot.T).mean(axis=0)
    roll = np.arctan2(f[1], f[2])
    pitch = np.arctan2(-f[0], np.hypot(f[1], f[2]))
    return Rotation.from_euler("xyz", [roll, pitch, 0.0])


class Preintegrator:
    """gtsam PreintegratedImuMeasurements between two sweeps: predicts the next sensor pose from
    the current pose and velocity (bias held at the configured value)."""

    def __init__(self, track: ImuTrack, acc_noise: float = 3.99e-3, gyro_noise: float = 1.56e-3,
                 gravity: float = 9.80511) -> None:
        import gtsam

        self.gtsam = gtsam
        self.track = track
        p = gtsam.PreintegrationParams.MakeSharedU(gravity)
        p.setAccelerometerCovariance(np.eye(3) * acc_noise ** 2)
        p.setGyroscopeCovariance(np.eye(3) * gyro_noise ** 2)
        p.setIntegrationCovariance(np.eye(3) * 1e-8)
        self.params = p
        self.bias = gtsam.imuBias.ConstantBias()

    def predict(self, pose: np.ndarray, velocity: np.ndarray, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        gtsam = self.gtsam
        pim = gtsam.PreintegratedImuMeasurements(self.params, self.bias)
        s = self.track.stamps
        i0, i1 = np.searchsorted(s, t0, side="right") - 1, np.searchsorted(s, t1, side="left")
        for k in range(max(i0, 0), min(i1, s.size - 1)):
            a, b = max(s[k], t0), min(s[k + 1], t1)
            if b > a:  # dt <= 0 would raise in gtsam (LIO-SAM#247)
                pim.integrateMeasurement(self.track.acc[k], self.track.gyro[k], b - a)
        state = gtsam.NavState(gtsam.Pose3(pose), np.asarray(velocity, float))
        nxt = pim.predict(state, self.bias)
        return nxt.pose().matrix(), np.asarray(nxt.velocity())
