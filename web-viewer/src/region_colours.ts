// The regions' colours: fixed blue, handles from a cycle. Shared by the mesh display and the
// Regions panel's legend.
import * as THREE from "three";

const REGION_COLOURS = [
  0x3b6fd8, // fixed
  0xe0483a,
  0x3fb950,
  0xd29922,
  0xb062d9,
  0x2fb8b0,
  0xe06fa8,
].map((c) => new THREE.Color(c));

/** Label 0: fixed; h ≥ 1: handle h. */
export function regionColour(label: number): THREE.Color {
  return label === 0 ? REGION_COLOURS[0] : REGION_COLOURS[1 + ((label - 1) % (REGION_COLOURS.length - 1))];
}

export function regionColourCss(label: number): string {
  return `#${regionColour(label).getHexString()}`;
}
