"""Regenerate the figures of docs/: ``python docs/figures.py`` (from the repository root)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from matplotlib.figure import Figure

from fisheyemotion import calib, synth

OUT = Path(__file__).parent / "img"


def epipolar_circle() -> None:
    fig = Figure(figsize=(10, 4.6), layout="constrained")
    side, circle = fig.subplots(1, 2)
    # Side view in the epipolar plane: cameras C' (current) and C (previous), ray p, road.
    c1, c0 = np.array([0.0, 1.0]), np.array([-1.2, 1.0])
    p = np.array([np.cos(-0.45), np.sin(-0.45)])
    delta = 1.0 / -p[1]
    road_pt = c0 + delta * p
    side.axhline(0, color="0.4")
    side.text(3.2, 0.05, "road", color="0.4")
    side.plot(*zip(c0, c0 + 1.7 * delta * p, strict=True), "k-", lw=1)
    for lam, col in ((0.6 * delta, "tab:orange"), (1.5 * delta, "tab:red")):
        x = c0 + lam * p
        side.plot(*zip(c1, x, strict=True), "--", color=col, lw=1)
        side.plot(*x, "o", color=col)
    side.plot(*zip(c1, road_pt, strict=True), "-", color="tab:green", lw=1)
    side.plot(*road_pt, "s", color="tab:green")
    side.plot(*c0, "ko")
    side.plot(*c1, "ko")
    side.annotate("C (previous)", c0 + [-0.2, 0.12])
    side.annotate("C' (current)", c1 + [0.05, 0.12])
    side.annotate("P = C + delta p (road)", road_pt + [0.1, -0.18], color="tab:green")
    side.annotate("above road: xi_p side", c0 + 0.6 * delta * p + [-0.4, 0.15], color="tab:orange")
    side.annotate("below road: xi_h side", c0 + 1.5 * delta * p + [0.05, -0.05], color="tab:red")
    side.set_aspect("equal")
    side.set_xlim(-1.6, 4.2)
    side.set_ylim(-1.0, 1.5)
    side.set_title("X = C + lambda p seen from C': X - C' = b e' + lambda p", fontsize=10)
    side.axis("off")
    # The epipolar great circle seen from C': e' at 0, p at Theta.
    theta, phi_r = 2.2, 1.3
    t = np.linspace(-np.pi, np.pi, 400)
    circle.plot(np.cos(t), np.sin(t), color="0.8")
    arcs = [((0, phi_r), "tab:orange", "0 <= phi < phi_r: above road -> xi_p"),
            ((phi_r, theta), "tab:red", "phi_r < phi <= Theta: below road -> xi_h"),
            ((theta, theta + np.pi), "tab:purple", "Theta < phi < Theta + pi: behind C' -> xi_d (paper)"),
            ((theta - np.pi, 0), "tab:blue", "Theta - pi < phi < 0: behind C -> xi_d (both views)")]
    for (a, b), col, label in arcs:
        s = np.linspace(a, b, 100)
        circle.plot(1.0 * np.cos(s), 1.0 * np.sin(s), color=col, lw=4, label=label)
    for ang, name in ((0, "e'"), (theta, "p"), (phi_r, "p'_r")):
        circle.plot(np.cos(ang), np.sin(ang), "ko")
        circle.annotate(name, (1.12 * np.cos(ang) - 0.05, 1.12 * np.sin(ang)), fontsize=11)
    circle.set_aspect("equal")
    circle.axis("off")
    circle.legend(loc="lower left", fontsize=7.5, frameon=False, bbox_to_anchor=(-0.05, -0.18))
    circle.set_title("Where p'_Pi may lie on the epipolar circle (angle phi from e')", fontsize=10)
    fig.savefig(OUT / "epipolar_circle.png", dpi=100)


def scenario_samples(frame: int = 10, street_frame: int = 36, names=None) -> None:
    """Frame 10 of each scenario (36 of the 48-frame streets, when their pedestrians are out)."""
    cam = calib.load(Path(__file__).parents[1] / "data" / "calib" / "front_kb_640x480.yaml")
    for name in names or synth.list_scenarios():
        sc = synth.load_scenario(name)
        r = synth.Renderer(cam, sc)
        truth = r.render(street_frame if name.startswith("street") else frame)
        img = truth.image.copy()
        edges = cv2.Canny(truth.moving, 50, 150) > 0
        img[edges] = (0, 255, 0)
        small = cv2.resize(img, (320, 240), interpolation=cv2.INTER_AREA)
        cv2.imwrite(str(OUT / f"scenario_{name}.png"), small)


if __name__ == "__main__":
    OUT.mkdir(exist_ok=True)
    epipolar_circle()
    scenario_samples()
