"""The GNSS track's filter with the multipath offset as a state and its change points as hypotheses.

Float fixes carry multipath jumps: a horizontal offset that comes on, holds for seconds and goes
off (0.5-3 m; docs/simulation.md). The step filter (gnss_track.TrackFilter) decides once, per fix,
whether a fix is a jump (its gate and step rules) and a wrong decision stays; below its gate it follows
a jump. Here each hypothesis is a Kalman filter on [x, y, vx, vy, bx, by] (ENU, m, m/s; b the
multipath offset, zero and exact while no jump is on) with a history of change points: at every fix
each hypothesis branches into "nothing changed", "a jump came on" (b drawn afresh, sigma
`jump_sigma_m`; also a change of a jump that is on) and, while one is on, "it went off" (b back to
exactly zero). Each branch is weighted by its prior (a rate per second over the fix interval) and by
its innovation likelihood; the `keep` likeliest hypotheses survive. A jump is told from motion by
the constant-velocity model: a base at walking pace does not step by a metre in 0.2 s. No decision is
final: a jump first explained as motion is taken back when a later fix makes the branch that put
it in b likelier. The track reads the posterior mean of position and velocity over the hypotheses
(no jump offset in it)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

H = np.c_[np.eye(2), np.zeros((2, 2)), np.eye(2)]  # a fix sees the position plus the offset


@dataclass(kw_only=True)
class Hypothesis:
    """One history of jump changes: its filter state (6) and covariance, log weight, whether a jump is on."""

    x: np.ndarray
    p: np.ndarray
    log_w: float
    on: bool


@dataclass(kw_only=True)
class OffsetBank:
    """A bank of constant-velocity filters with a multipath offset state; the same interface as
    gnss_track.TrackFilter (update / predict / fresh, x the state [x, y, vx, vy] of the likeliest)."""

    accel_sigma: float  # m/s^2, white acceleration
    jump_sigma_m: float = 1.5  # prior sigma of a jump's offset per axis, m
    on_rate_hz: float = 0.1  # prior rate of a jump coming on (or changing), 1/s
    off_rate_hz: float = 0.25  # prior rate of a jump that is on going off, 1/s
    keep: int = 20  # hypotheses kept after each fix
    max_gap_s: float = 2.0  # no fix for longer: the bank starts again at the next fix
    sigma_floor_m: float = 0.0  # a fix's sigma is taken as at least this (m)
    hypotheses: list[Hypothesis] = field(default_factory=list)  # likeliest first
    x: np.ndarray | None = None
    t: float = 0.0
    offset: np.ndarray = field(default_factory=lambda: np.zeros(2))  # the likeliest hypothesis's offset, m
    accepted: int = 0
    rejected: int = 0  # kept for the step filter's interface: every fix enters

    def fresh(self, t: float) -> bool:
        """A fix was taken within max_gap_s before t."""
        return self.x is not None and t - self.t <= self.max_gap_s

    def _predict_one(self, h: Hypothesis, t: float) -> tuple[np.ndarray, np.ndarray]:
        dt = max(t - self.t, 0.0)
        f = np.eye(6)
        f[0, 2] = f[1, 3] = dt
        g = np.zeros((6, 2))
        g[:2], g[2:4] = dt * dt / 2 * np.eye(2), dt * np.eye(2)
        return f @ h.x, f @ h.p @ f.T + self.accel_sigma ** 2 * (g @ g.T)

    def predict(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean of [x, y, vx, vy] at t over the hypotheses, and the likeliest one's covariance."""
        assert self.hypotheses
        states = [self._predict_one(h, t) for h in self.hypotheses]
        w = np.exp([h.log_w for h in self.hypotheses])
        mean = (w / w.sum()) @ np.array([s[0][:4] for s in states])
        return mean, states[0][1][:4, :4]

    def update(self, t: float, z: np.ndarray, sigma: float) -> bool:
        """One fix (ENU xy, m; its 1-sigma, m). After max_gap_s without one the bank starts again here."""
        sigma = max(sigma, self.sigma_floor_m)
        if self.x is None or t - self.t > self.max_gap_s:
            p = np.diag([sigma ** 2, sigma ** 2, 1.0, 1.0, 0.0, 0.0])
            self.hypotheses = [Hypothesis(x=np.r_[z, 0.0, 0.0, 0.0, 0.0], p=p, log_w=0.0, on=False)]
        else:
            dt = max(t - self.t, 0.0)
            p_on, p_off = 1.0 - np.exp(-self.on_rate_hz * dt), 1.0 - np.exp(-self.off_rate_hz * dt)
            branches = [b for h in self.hypotheses for b in self._branches(h, t, (p_on, p_off))]
            for b in branches:
                _absorb(b, z, sigma)
            branches.sort(key=lambda b: -b.log_w)
            best = branches[0].log_w
            self.hypotheses = branches[: max(self.keep, 1)]
            for b in self.hypotheses:
                b.log_w -= best
        self.t = t
        self.x, self.offset = self.hypotheses[0].x[:4].copy(), self.hypotheses[0].x[4:].copy()
        self.accepted += 1
        return True

    def _branches(self, h: Hypothesis, t: float, probs: tuple[float, float]) -> list[Hypothesis]:
        """h predicted to t and split: nothing changed, a jump came on (or changed), a jump went off."""
        p_on, p_off = probs
        x, p = self._predict_one(h, t)
        stay = 1.0 - p_on - (p_off if h.on else 0.0)
        out = [Hypothesis(x=x, p=p, log_w=h.log_w + float(np.log(max(stay, 1e-12))), on=h.on)]
        new_x, new_p = _offset_reset(x, p, self.jump_sigma_m ** 2)
        out.append(Hypothesis(x=new_x, p=new_p, log_w=h.log_w + float(np.log(max(p_on, 1e-12))), on=True))
        if h.on:
            off_x, off_p = _offset_reset(x, p, 0.0)
            out.append(Hypothesis(x=off_x, p=off_p, log_w=h.log_w + float(np.log(max(p_off, 1e-12))), on=False))
        return out


def _offset_reset(x: np.ndarray, p: np.ndarray, var: float) -> tuple[np.ndarray, np.ndarray]:
    """The state with the offset drawn afresh: zero mean, variance var (m^2) per axis, uncorrelated."""
    x, p = x.copy(), p.copy()
    x[4:] = 0.0
    p[4:, :] = 0.0
    p[:, 4:] = 0.0
    p[4, 4] = p[5, 5] = var
    return x, p


def _absorb(h: Hypothesis, z: np.ndarray, sigma: float) -> None:
    """Kalman update of h with the fix z (m, sigma m); its log weight gains the innovation's log likelihood."""
    nu = z - H @ h.x
    s = H @ h.p @ H.T + sigma ** 2 * np.eye(2)
    s_inv = np.linalg.inv(s)
    gain = h.p @ H.T @ s_inv
    h.log_w += -0.5 * float(nu @ s_inv @ nu + np.log(np.linalg.det(s)))
    h.x = h.x + gain @ nu
    p = (np.eye(6) - gain @ H) @ h.p
    h.p = (p + p.T) / 2
