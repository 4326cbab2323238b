// Snapping steps for the gizmo, as in Blender / the three.js editor: with Ctrl held, rotation
// goes in 15° steps (5° with Shift too) and moves in grid steps; the Snap checkbox makes the
// grid permanent. null: free.

export interface SnapInput {
  ctrl: boolean;
  shift: boolean;
  /** The Snap checkbox. */
  enabled: boolean;
  /** Grid step in model units (≤ 0 or NaN: no grid). */
  grid: number;
}

export interface SnapSteps {
  translation: number | null;
  rotation: number | null; // radians
  scale: number | null;
}

export function snapSteps({ ctrl, shift, enabled, grid }: SnapInput): SnapSteps {
  const on = ctrl || enabled;
  const step = Number.isFinite(grid) && grid > 0 ? grid : null;
  return {
    translation: on ? step : null,
    rotation: on ? ((shift ? 5 : 15) * Math.PI) / 180 : null,
    scale: on ? 0.1 : null,
  };
}
