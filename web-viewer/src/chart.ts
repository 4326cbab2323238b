// A small canvas line chart: one measure against β from Sweep. Values below the noise floor
// read 0 and the y axis never spans less than it (noise_floor.ts).
import { fmt } from "./colormap";
import { chartRange, denoise } from "./noise_floor";

export interface SweepPoint {
  beta: number;
  value: number;
}

export function drawChart(
  canvas: HTMLCanvasElement,
  points: SweepPoint[],
  label: string,
  currentBeta: number | null,
  floor = 0,
): void {
  const ctx = canvas.getContext("2d");
  if (!ctx) return;
  const w = canvas.width;
  const h = canvas.height;
  ctx.clearRect(0, 0, w, h);
  ctx.font = "11px system-ui, sans-serif";
  ctx.fillStyle = "#aaa";
  if (points.length === 0) {
    ctx.textAlign = "center";
    ctx.fillText("Run a sweep to chart measures against β", w / 2, h / 2);
    return;
  }
  const left = 58;
  const right = 8;
  const top = 16;
  const bottom = 26;
  points = points.map((p) => ({ beta: p.beta, value: denoise(p.value, floor) }));
  const xs = points.map((p) => p.beta);
  const xMin = Math.min(...xs, 0);
  const xMax = Math.max(...xs, 1e-9);
  const [yMin, yMax] = chartRange(points.map((p) => p.value), floor);
  const X = (x: number) => left + ((x - xMin) / (xMax - xMin)) * (w - left - right);
  const Y = (y: number) => h - bottom - ((y - yMin) / (yMax - yMin)) * (h - top - bottom);

  ctx.strokeStyle = "#555";
  ctx.lineWidth = 1;
  ctx.beginPath();
  ctx.moveTo(left, top);
  ctx.lineTo(left, h - bottom);
  ctx.lineTo(w - right, h - bottom);
  ctx.stroke();

  ctx.fillStyle = "#aaa";
  ctx.textAlign = "right";
  ctx.textBaseline = "middle";
  for (let i = 0; i <= 4; i++) {
    const y = yMin + ((yMax - yMin) * i) / 4;
    ctx.fillText(Number(y.toPrecision(3)).toString(), left - 4, Y(y));
    ctx.strokeStyle = "#333";
    ctx.beginPath();
    ctx.moveTo(left, Y(y));
    ctx.lineTo(w - right, Y(y));
    ctx.stroke();
  }
  ctx.textAlign = "center";
  ctx.textBaseline = "top";
  const step = xMax - xMin > 0.5 ? 0.2 : xMax - xMin > 0.2 ? 0.1 : (xMax - xMin) / 4;
  for (let x = Math.ceil(xMin / step) * step; x <= xMax + 1e-9; x += step) {
    ctx.fillText(fmt(Number(x.toFixed(6))), X(x), h - bottom + 4);
  }
  ctx.textAlign = "left";
  ctx.fillText(`${label} vs β`, left + 4, 2);

  if (currentBeta !== null && currentBeta >= xMin && currentBeta <= xMax) {
    ctx.strokeStyle = "#e9a23b";
    ctx.setLineDash([3, 3]);
    ctx.beginPath();
    ctx.moveTo(X(currentBeta), top);
    ctx.lineTo(X(currentBeta), h - bottom);
    ctx.stroke();
    ctx.setLineDash([]);
  }
  ctx.strokeStyle = "#4fc3f7";
  ctx.lineWidth = 2;
  ctx.beginPath();
  points.forEach((p, i) => (i === 0 ? ctx.moveTo(X(p.beta), Y(p.value)) : ctx.lineTo(X(p.beta), Y(p.value))));
  ctx.stroke();
  ctx.fillStyle = "#4fc3f7";
  for (const p of points) {
    ctx.beginPath();
    ctx.arc(X(p.beta), Y(p.value), 2.5, 0, Math.PI * 2);
    ctx.fill();
  }
}
