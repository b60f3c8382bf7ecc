// A keyframe image with the regions' boxes drawn on it, on which the operator drags a new region.
// Boxes are in the keyframe's pixels (keyframe width x height); the JPEG may be smaller.

export class KeyframeCanvas {
  constructor(canvas, on_drawn) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.image = null;
    this.keyframe = null;  // {t_ns, width, height}
    this.boxes = [];       // [{box_px, state}]
    this.drag = null;      // canvas pixels
    this.drawn = null;     // keyframe pixels [x, y, w, h]
    this.on_drawn = on_drawn;
    this.missing = false;  // the image could not be loaded
    canvas.addEventListener('pointerdown', (e) => {
      canvas.setPointerCapture(e.pointerId);
      this.start(e);
    });
    canvas.addEventListener('pointermove', (e) => this.move(e));
    canvas.addEventListener('pointerup', () => this.end());
    canvas.addEventListener('pointercancel', () => this.end());
  }

  // Canvas pixels of a mouse event (the canvas is scaled by CSS).
  at(e) {
    const r = this.canvas.getBoundingClientRect();
    return [((e.clientX - r.left) * this.canvas.width) / r.width, ((e.clientY - r.top) * this.canvas.height) / r.height];
  }

  scale() {
    return this.keyframe ? this.canvas.width / this.keyframe.width : 1;
  }

  show(keyframe, url, boxes) {
    this.boxes = boxes;
    if (this.keyframe && keyframe && this.keyframe.t_ns === keyframe.t_ns) {
      this.draw();
      return;
    }
    this.keyframe = keyframe;
    this.drawn = null;
    this.on_drawn(null);
    if (!keyframe) {
      this.image = null;
      this.draw();
      return;
    }
    this.canvas.width = 640;
    this.canvas.height = Math.round((640 * keyframe.height) / keyframe.width);
    this.image = null;
    this.missing = false;
    const image = new Image();
    image.onload = () => {
      if (this.keyframe === keyframe) {
        this.image = image;
        this.draw();
      }
    };
    image.onerror = () => {
      if (this.keyframe === keyframe) {
        this.missing = true;
        this.draw();
      }
    };
    image.src = url;
    this.draw();
  }

  // Forgets the dragged rectangle (it was sent).
  clear() {
    this.drawn = null;
    this.on_drawn(null);
    this.draw();
  }

  draw() {
    const { ctx, canvas } = this;
    ctx.fillStyle = '#000';
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    if (this.image) ctx.drawImage(this.image, 0, 0, canvas.width, canvas.height);
    const note = !this.keyframe ? 'no keyframe images yet' : this.missing ? 'this keyframe has no image' : null;
    if (note) {
      ctx.fillStyle = '#888';
      ctx.font = '16px system-ui, sans-serif';
      ctx.fillText(note, 12, 28);
    }
    const s = this.scale();
    ctx.lineWidth = 2;
    for (const b of this.boxes) {
      ctx.strokeStyle = { proposed: '#f0b429', confirmed: '#3ddc84', rejected: '#ff4d4d' }[b.state] || '#fff';
      ctx.strokeRect(b.box_px[0] * s, b.box_px[1] * s, b.box_px[2] * s, b.box_px[3] * s);
    }
    const r = this.drag ? this.drag_rect() : this.drawn ? this.drawn.map((v) => v * s) : null;
    if (r) {
      ctx.strokeStyle = '#4da3ff';
      ctx.setLineDash([6, 4]);
      ctx.strokeRect(...r);
      ctx.setLineDash([]);
    }
  }

  drag_rect() {
    const [x0, y0] = this.drag.from, [x1, y1] = this.drag.to;
    return [Math.min(x0, x1), Math.min(y0, y1), Math.abs(x1 - x0), Math.abs(y1 - y0)];
  }

  start(e) {
    if (!this.keyframe) return;
    this.drag = { from: this.at(e), to: this.at(e) };
  }

  move(e) {
    if (!this.drag) return;
    this.drag.to = this.at(e);
    this.draw();
  }

  end() {
    if (!this.drag) return;
    const r = this.drag_rect();
    this.drag = null;
    const s = this.scale();
    this.drawn = r[2] >= 4 && r[3] >= 4 ? r.map((v) => Math.round(v / s)) : null;
    this.on_drawn(this.drawn);
    this.draw();
  }
}
