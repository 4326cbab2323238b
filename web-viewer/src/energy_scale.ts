// Whether energies are shown, and the value at the top of their colour ramp.
import { scaleTop } from "./colormap";
import type { SessionState } from "./state";

/** The top of the energy colour ramp, or null when the mesh shows no energies. */
export function energyTop(state: SessionState): number | null {
  const energies = state.mesh?.energies;
  if (state.energyMapping === "off" || !energies || energies.length !== state.mesh!.m) return null;
  return scaleTop(state.energyMapping, energies, state.truncation);
}
