// camera.js — the viewer's map camera: a point on the ground looked at from
// a distance, a heading and a pitch, moved by pointer events (mouse, pen and
// touch alike) and the wheel. It yields the camera objects renderFrame takes
// (web/src/render, prep::render::Camera's fields, metres relative to the
// package origin).

/** @typedef {import("../src/render/camera.js").Camera} Camera */

const DEG = Math.PI / 180;

export class MapCamera {
  /**
   * Frames `extent` ([xmin, ymin, xmax, ymax], metres relative to the origin)
   * from the south, at `pitch` degrees below the horizon.
   * @param {number[]} extent
   * @param {number} z the ground height to look at
   * @param {number} [pitch]
   */
  constructor(extent, z, pitch = 50) {
    this.fovYDeg = 45;
    /** @type {number[]} */
    this.target = [(extent[0] + extent[2]) / 2, (extent[1] + extent[3]) / 2, z];
    const radius = 0.5 * Math.hypot(extent[2] - extent[0], extent[3] - extent[1]);
    this.distance = Math.max(10, radius / Math.sin(this.fovYDeg * DEG / 2));
    this.heading = 0;  // degrees, 0: looking north
    this.pitch = pitch;  // degrees below the horizon
  }

  /**
   * The renderFrame camera of this view.
   * @returns {Camera}
   */
  camera() {
    const h = this.heading * DEG, p = this.pitch * DEG, d = this.distance, t = this.target;
    // Looking along (sin h cos p, cos h cos p, -sin p) at the target.
    const eye = [t[0] - d * Math.sin(h) * Math.cos(p), t[1] - d * Math.cos(h) * Math.cos(p),
                 t[2] + d * Math.sin(p)];
    // Straight down, "up" on the screen is the heading (render's camera takes north then).
    const up = this.pitch >= 89.99 ? [Math.sin(h), Math.cos(h), 0] : [0, 0, 1];
    return {
      projection: "perspective", eye, target: t.slice(), up, fovYDeg: this.fovYDeg,
      orthoW: 0, orthoH: 0, near: Math.max(0.1, d * 1e-3), depthRange: 4 * d, topdownExtent: null,
    };
  }

  /** Ground metres per screen pixel at the target, for a canvas `height` pixels high. @param {number} height */
  metresPerPixel(height) {
    return 2 * this.distance * Math.tan(this.fovYDeg * DEG / 2) / Math.max(1, height);
  }

  /** Moves the target by a screen drag of (dx, dy) pixels. @param {number} dx @param {number} dy @param {number} height */
  pan(dx, dy, height) {
    const m = this.metresPerPixel(height), h = this.heading * DEG;
    // Screen right is (cos h, -sin h), screen up (sin h, cos h) on the ground.
    const sy = dy / Math.max(0.2, Math.sin(this.pitch * DEG));
    this.target[0] += -dx * m * Math.cos(h) + sy * m * Math.sin(h);
    this.target[1] += dx * m * Math.sin(h) + sy * m * Math.cos(h);
  }

  /** Zooms by `factor` (< 1: closer). @param {number} factor */
  zoom(factor) {
    this.distance = Math.min(1e7, Math.max(1, this.distance * factor));
  }

  /** Rotates by `dHeading` and tilts by `dPitch` degrees. @param {number} dHeading @param {number} dPitch */
  orbit(dHeading, dPitch) {
    this.heading = (((this.heading + dHeading) % 360) + 360) % 360;
    this.pitch = Math.min(90, Math.max(5, this.pitch + dPitch));
  }
}

/**
 * Wires pointer and wheel events of `el` to `cam`: one-pointer drag pans
 * (with the right button or Ctrl: rotates and tilts), the wheel zooms, two
 * pointers pinch-zoom, rotate and (moving together up or down) tilt.
 * Calls `changed` after every move.
 * @param {HTMLElement} el
 * @param {MapCamera} cam
 * @param {() => void} changed
 */
export function attachControls(el, cam, changed) {
  /** @type {Map<number, {x: number, y: number, orbit: boolean}>} */
  const down = new Map();
  el.addEventListener("contextmenu", (e) => e.preventDefault());
  el.addEventListener("pointerdown", (e) => {
    el.setPointerCapture(e.pointerId);
    down.set(e.pointerId, { x: e.clientX, y: e.clientY, orbit: e.button === 2 || e.ctrlKey });
  });
  const up = (/** @type {PointerEvent} */ e) => { down.delete(e.pointerId); };
  el.addEventListener("pointerup", up);
  el.addEventListener("pointercancel", up);
  el.addEventListener("pointermove", (e) => {
    const p = down.get(e.pointerId);
    if (!p) return;
    const dx = e.clientX - p.x, dy = e.clientY - p.y;
    if (down.size === 1) {
      if (p.orbit) cam.orbit(-dx * 0.3, dy * 0.2);
      else cam.pan(dx, dy, el.clientHeight);
    } else if (down.size === 2) {
      const [a, b] = [...down.entries()];
      const other = a[0] === e.pointerId ? b[1] : a[1];
      const before = { x: p.x - other.x, y: p.y - other.y };
      const after = { x: e.clientX - other.x, y: e.clientY - other.y };
      const d0 = Math.hypot(before.x, before.y), d1 = Math.hypot(after.x, after.y);
      if (d0 > 0 && d1 > 0) cam.zoom(d0 / d1);
      const turn = Math.atan2(after.y, after.x) - Math.atan2(before.y, before.x);
      cam.orbit(-turn / DEG, dy * 0.1);
    }
    p.x = e.clientX;
    p.y = e.clientY;
    changed();
  });
  el.addEventListener("wheel", (e) => {
    e.preventDefault();
    cam.zoom(Math.exp(e.deltaY * (e.deltaMode === 1 ? 0.05 : 0.0015)));
    changed();
  }, { passive: false });
}
