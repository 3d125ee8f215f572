// The placement step of the tracking panel: where tracking starts. The faces the finder found in
// the frame are shown with their landmarks; the most confident is selected, a click selects
// another. The box (the model's mean face fitted in it) is the manual fallback: drag it, resize
// it by its corner, or move it with the keys; editing it deselects the found face. For the
// webcam the box is the guide (an oval). All coordinates are work-frame pixels.

import { bounds, drawLandmarks, GUIDE, MESH, FOUND, FOUND_OTHER } from './face-draw.js';

/** The arrow keys' moves of the box, in steps: [x, y]. */
const ARROWS = new Map([
  ['ArrowLeft', [-1, 0]],
  ['ArrowRight', [1, 0]],
  ['ArrowUp', [0, -1]],
  ['ArrowDown', [0, 1]],
]);

export class Placement {
  /** `meanShape`: the model's mean landmarks (any placement; only their proportions are used). */
  constructor(meanShape) {
    this.meanShape = meanShape;
    this.meanBox = bounds(meanShape);
    this.aspect = this.meanBox.h / this.meanBox.w; // a box is the mean shape's bounding box
    this.box = null;
    this.faces = [];
    this.selected = -1;
    this.drag = null;
    this.touched = false; // the box was placed by hand (since the last setFaces / reset)
  }

  /** The selected found face, or null (none found, or the box was edited). */
  get face() {
    return this.selected >= 0 ? this.faces[this.selected] : null;
  }

  /** A box of the mean shape's proportions around landmarks. */
  boxAround(landmarks) {
    const b = bounds(landmarks);
    const h = b.w * this.aspect > b.h ? b.w * this.aspect : b.h;
    const w = h / this.aspect;
    return { x: b.x + b.w / 2 - w / 2, y: b.y + b.h / 2 - h / 2, w, h };
  }

  /**
   * The found faces (work pixels, most confident first): the first is selected, unless the box
   * was placed by hand meanwhile (`keepBox`), which then stays.
   */
  setFaces(faces, keepBox = false) {
    this.faces = faces;
    if (keepBox && this.touched) this.selected = -1;
    else {
      this.touched = false;
      this.select(faces.length ? 0 : -1);
    }
  }

  select(i) {
    this.selected = i;
    if (i >= 0) this.box = this.boxAround(this.faces[i].landmarks);
  }

  /** A default box: around `landmarks` when given, else centred (the webcam guide, a bit lower). */
  placeDefault(W, H, webcam, landmarks = null) {
    if (landmarks) {
      this.box = this.boxAround(landmarks);
      return;
    }
    const h = H * (webcam ? 0.5 : 0.45);
    const w = h / this.aspect;
    this.box = { x: (W - w) / 2, y: (H - h) / 2 + (webcam ? H * 0.04 : 0), w, h };
  }

  clamp(W, H) {
    const b = this.box;
    b.h = Math.min(Math.max(b.h, 8), H * 1.5);
    b.w = b.h / this.aspect;
    b.x = Math.min(Math.max(b.x, -b.w / 2), W - b.w / 2);
    b.y = Math.min(Math.max(b.y, -b.h / 2), H - b.h / 2);
  }

  /** What a pointer at `p` would do: "corner" | "inside" | "face:<i>" | "outside". */
  hit(p, handle) {
    const b = this.box;
    if (b && Math.abs(p.x - (b.x + b.w)) < handle && Math.abs(p.y - (b.y + b.h)) < handle) return 'corner';
    for (let i = 0; i < this.faces.length; i++) {
      if (i === this.selected) continue;
      const f = this.faces[i].box;
      if (p.x >= f.x && p.x <= f.x + f.width && p.y >= f.y && p.y <= f.y + f.height) return `face:${i}`;
    }
    if (b && p.x >= b.x && p.x <= b.x + b.w && p.y >= b.y && p.y <= b.y + b.h) return 'inside';
    return 'outside';
  }

  /** Pointer pressed at `p`: selects a found face, or starts moving / resizing / drawing the box. */
  pointerDown(p, handle) {
    const h = this.hit(p, handle);
    if (h.startsWith('face:')) {
      this.select(Number(h.slice(5)));
      this.drag = null;
      return;
    }
    const b = this.box;
    this.drag =
      h === 'corner'
        ? { kind: 'resize', x0: b.x, y0: b.y }
        : h === 'inside'
          ? { kind: 'move', dx: p.x - b.x, dy: p.y - b.y }
          : { kind: 'new', x0: p.x, y0: p.y };
  }

  /** Pointer moved to `p` while pressed: returns whether the box changed. */
  pointerMove(p, W, H) {
    const d = this.drag;
    if (!d) return false;
    if (!this.box) this.box = { x: p.x, y: p.y, w: 8 / this.aspect, h: 8 };
    const b = this.box;
    if (d.kind === 'move') {
      b.x = p.x - d.dx;
      b.y = p.y - d.dy;
    } else {
      // Keep the mean shape's aspect: the larger of the two drag extents decides the size.
      const h = Math.max(8, Math.abs(p.y - d.y0), Math.abs(p.x - d.x0) * this.aspect);
      const w = h / this.aspect;
      b.x = p.x >= d.x0 ? d.x0 : d.x0 - w;
      b.y = p.y >= d.y0 ? d.y0 : d.y0 - h;
      b.w = w;
      b.h = h;
    }
    this.selected = -1; // the box is placed by hand now
    this.touched = true;
    this.clamp(W, H);
    return true;
  }

  pointerUp() {
    this.drag = null;
  }

  /** Arrow keys move the box, + and - resize it, Tab cycles the found faces: whether handled. */
  key(e, step, W, H) {
    if (e.key === 'Tab' && this.faces.length > 1 && !e.altKey && !e.ctrlKey && !e.metaKey) {
      const n = this.faces.length;
      this.select(((this.selected < 0 ? 0 : this.selected) + (e.shiftKey ? n - 1 : 1)) % n);
      return true;
    }
    const b = this.box;
    if (!b) return false;
    const grow = (f) => {
      const cx = b.x + b.w / 2;
      const cy = b.y + b.h / 2;
      b.h *= f;
      b.w = b.h / this.aspect;
      b.x = cx - b.w / 2;
      b.y = cy - b.h / 2;
    };
    const move = ARROWS.get(e.key);
    if (move) {
      b.x += move[0] * step;
      b.y += move[1] * step;
    } else if (['+', '=', 'PageUp'].includes(e.key)) {
      grow(1.05);
    } else if (['-', '_', 'PageDown'].includes(e.key)) {
      grow(1 / 1.05);
    } else {
      return false;
    }
    this.selected = -1;
    this.touched = true;
    this.clamp(W, H);
    return true;
  }

  /** Draw the placement over the frame: the found faces, or the box (file) / oval (webcam). */
  draw(g, map, s, lw, dpr, { webcam = false, hot = false } = {}) {
    if (this.face && !webcam) {
      this.faces.forEach((f, i) => {
        if (i === this.selected) return;
        drawLandmarks(g, f.landmarks, map, FOUND_OTHER, lw, { points: false });
        this.drawFaceBox(g, map, f.box, FOUND_OTHER, lw, dpr, i);
      });
      const f = this.faces[this.selected];
      this.drawFaceBox(g, map, f.box, FOUND, lw * 1.5, dpr, this.selected);
      drawLandmarks(g, f.landmarks, map, FOUND, lw);
      return;
    }
    const b = this.box;
    if (!b) return;
    // The mean shape in the box (as startFromBox will place it).
    const m = this.meanBox;
    const k = Math.min(b.w / m.w, b.h / m.h);
    const cx = b.x + b.w / 2;
    const cy = b.y + b.h / 2;
    const mx = m.x + m.w / 2;
    const my = m.y + m.h / 2;
    const shapeMap = (x, y) => map(cx + (x - mx) * k, cy + (y - my) * k);
    if (webcam) {
      // The guide: an oval around the face box, the rest of the picture dimmed.
      const [X, Y] = map(cx, cy - b.h * 0.1);
      const rx = b.w * 0.62 * s;
      const ry = b.h * 0.72 * s;
      g.save();
      g.fillStyle = 'rgba(10, 11, 14, 0.45)';
      g.beginPath();
      g.rect(0, 0, g.canvas.width, g.canvas.height);
      g.ellipse(X, Y, rx, ry, 0, 0, Math.PI * 2);
      g.fill('evenodd');
      g.strokeStyle = hot ? MESH : GUIDE;
      g.lineWidth = lw * 2;
      g.setLineDash([8 * dpr, 6 * dpr]);
      g.beginPath();
      g.ellipse(X, Y, rx, ry, 0, 0, Math.PI * 2);
      g.stroke();
      g.restore();
      drawLandmarks(g, this.meanShape, shapeMap, 'rgba(124, 196, 255, 0.55)', lw, { points: false });
      return;
    }
    // Faces found but the box placed by hand: the faces stay visible, faintly.
    for (const f of this.faces) drawLandmarks(g, f.landmarks, map, FOUND_OTHER, lw, { points: false });
    const [x0, y0] = map(b.x, b.y);
    const [x1, y1] = map(b.x + b.w, b.y + b.h);
    g.save();
    g.fillStyle = 'rgba(10, 11, 14, 0.35)';
    g.beginPath();
    g.rect(0, 0, g.canvas.width, g.canvas.height);
    g.rect(x0, y0, x1 - x0, y1 - y0);
    g.fill('evenodd');
    g.strokeStyle = GUIDE;
    g.lineWidth = lw * 1.5;
    g.strokeRect(x0, y0, x1 - x0, y1 - y0);
    const hs = 9 * dpr;
    g.fillStyle = GUIDE;
    g.fillRect(x1 - hs / 2, y1 - hs / 2, hs, hs);
    g.restore();
    drawLandmarks(g, this.meanShape, shapeMap, 'rgba(124, 196, 255, 0.8)', lw);
  }

  drawFaceBox(g, map, f, colour, lw, dpr, i) {
    const [x0, y0] = map(f.x, f.y);
    const [x1, y1] = map(f.x + f.width, f.y + f.height);
    const l = Math.min(x0, x1);
    g.save();
    g.strokeStyle = colour;
    g.lineWidth = lw;
    g.setLineDash([6 * dpr, 4 * dpr]);
    g.strokeRect(l, y0, Math.abs(x1 - x0), y1 - y0);
    if (this.faces.length > 1) {
      g.setLineDash([]);
      g.font = `600 ${Math.round(12 * dpr)}px system-ui, sans-serif`;
      g.fillStyle = colour;
      g.textBaseline = 'bottom';
      g.fillText(String(i + 1), l + 2 * dpr, y0 - 2 * dpr);
    }
    g.restore();
  }
}
