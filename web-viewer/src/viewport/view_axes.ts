// Named views along the model's axes, as in Blender's numeric keypad (1 front, 3 right, 7 top;
// Ctrl for the opposite side) and the axes view helper's six ends. Without the DOM (unit-tested).
//
// Blender's frame is z-up with the viewer of the front view on −y. A y-up model (glTF) is what
// Blender's glTF import turns into that frame (+y → +z, +z → −y), so for it the front view looks
// from +z and the top from +y — the three.js editor's views too. Right is +x either way.
export type Vec3 = [number, number, number];
export type UpAxis = "y" | "z";
export type ViewName = "front" | "back" | "right" | "left" | "top" | "bottom";
/** The axes view helper's ends (three's ViewHelper names its sprites so). */
export type AxisEnd = "posX" | "negX" | "posY" | "negY" | "posZ" | "negZ";

/** Where the viewer of the front view stands (target → camera), by up axis. */
function frontSide(up: UpAxis): Vec3 {
  return up === "z" ? [0, -1, 0] : [0, 0, 1];
}

function upVector(up: UpAxis): Vec3 {
  return up === "z" ? [0, 0, 1] : [0, 1, 0];
}

const neg = (v: Vec3): Vec3 => [-v[0], -v[1], -v[2]];

/** The unit direction target → camera of a named view. */
export function viewDirection(view: ViewName, up: UpAxis): Vec3 {
  switch (view) {
    case "front":
      return frontSide(up);
    case "back":
      return neg(frontSide(up));
    case "right":
      return [1, 0, 0];
    case "left":
      return [-1, 0, 0];
    case "top":
      return upVector(up);
    case "bottom":
      return neg(upVector(up));
  }
}

/** The direction target → camera when the helper's `end` is clicked: the camera goes to that end (the three.js editor's behaviour). */
export function axisEndDirection(end: AxisEnd): Vec3 {
  const s = end.startsWith("pos") ? 1 : -1;
  const k = end.endsWith("X") ? 0 : end.endsWith("Y") ? 1 : 2;
  const v: Vec3 = [0, 0, 0];
  v[k] = s;
  return v;
}

/**
 * `dir` (target → camera), nudged by `eps` towards the front side when it lies along the up axis.
 * OrbitControls keeps the camera off its poles and takes the view's roll from the camera's
 * horizontal offset, which straight above or below is undefined; this offset gives Blender's
 * top view (x right, the back (+y for z-up) up on screen) and bottom view (x right, the front
 * up). Any other direction is returned as it is.
 */
export function orbitSafeDirection(dir: Vec3, up: UpAxis, eps = 1e-4): Vec3 {
  const u = upVector(up);
  const along = dir[0] * u[0] + dir[1] * u[1] + dir[2] * u[2];
  if (Math.abs(along) < 0.999999) return dir;
  const f = frontSide(up);
  const v: Vec3 = [dir[0] + eps * f[0], dir[1] + eps * f[1], dir[2] + eps * f[2]];
  const len = Math.hypot(...v);
  return [v[0] / len, v[1] / len, v[2] / len];
}
