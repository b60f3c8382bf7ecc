// The 3D view: segments as coloured point clouds, the trajectory, the current camera pose and the
// welding regions' boxes and seams, in the robot's world frame (z up, metres).
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

const STATE_COLOURS = { proposed: 0xf0b429, confirmed: 0x3ddc84, rejected: 0xff4d4d };

// Colours are drawn as given: the points' colours are the camera's sRGB bytes, and three.js would
// otherwise treat vertex colours as linear and brighten them on output.
THREE.ColorManagement.enabled = false;

// 3x4 [R | t] row by row -> Matrix4.
export function matrix_from_rows(T) {
  const m = new THREE.Matrix4();
  m.set(T[0], T[1], T[2], T[3], T[4], T[5], T[6], T[7], T[8], T[9], T[10], T[11], 0, 0, 0, 1);
  return m;
}

export class MapScene {
  // Throws when WebGL is unavailable (the caller shows the panels without the view).
  constructor(container) {
    this.container = container;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
    this.renderer.setPixelRatio(window.devicePixelRatio);
    container.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x15181c);
    this.camera = new THREE.PerspectiveCamera(55, 1, 0.05, 5000);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(-8, -8, 8);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.addEventListener('change', () => this.render());
    const grid = new THREE.GridHelper(100, 100, 0x3a3f47, 0x262a30);
    grid.rotation.x = Math.PI / 2;  // the x-y plane of a z-up world
    this.scene.add(grid);
    this.segments = new Map();  // key -> {points, revision, full, sphere}
    this.trajectory = null;
    this.pose = new THREE.AxesHelper(0.6);
    this.pose.matrixAutoUpdate = false;
    this.pose.visible = false;
    this.scene.add(this.pose);
    this.regions = new THREE.Group();
    this.scene.add(this.regions);
    // The view frames the whole map as it grows until the operator moves it.
    this.operator_moved = false;
    this.controls.addEventListener('start', () => (this.operator_moved = true));
    new ResizeObserver(() => this.resize()).observe(container);
    this.resize();
  }

  resize() {
    const w = Math.max(1, this.container.clientWidth), h = Math.max(1, this.container.clientHeight);
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.render();
  }

  render() {
    this.renderer.render(this.scene, this.camera);
  }

  // Replaces (or adds) a segment's cloud. data: api.fetch_segment's result.
  set_segment(key, revision, data, full) {
    this.remove_segment(key);
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(data.positions, 3));
    geometry.setAttribute('color', new THREE.BufferAttribute(data.colors, 3, true));
    geometry.computeBoundingSphere();
    const material = new THREE.PointsMaterial({ size: full ? 2 : 3, sizeAttenuation: false, vertexColors: true });
    const points = new THREE.Points(geometry, material);
    this.scene.add(points);
    this.segments.set(key, { points, revision, full, sphere: geometry.boundingSphere });
    if (!this.operator_moved && data.count > 0) this.frame_all();
    this.render();
  }

  remove_segment(key) {
    const s = this.segments.get(key);
    if (!s) return;
    this.scene.remove(s.points);
    s.points.geometry.dispose();
    s.points.material.dispose();
    this.segments.delete(key);
  }

  // Segments thinned for the browser that the view is zoomed in on (the camera inside the segment's
  // bounding sphere): fetch them in full.
  segments_to_refine() {
    return [...this.segments.keys()].filter((key) => !this.segments.get(key).full && this.zoomed_in_on(key));
  }

  zoomed_in_on(key) {
    const s = this.segments.get(key);
    return s != null && this.camera.position.distanceTo(s.sphere.center) < Math.max(2.0, s.sphere.radius);
  }

  // Segments with points in the view, counting each segment id once.
  segments_drawn() {
    const ids = new Set();
    for (const [key, s] of this.segments) if (s.points.geometry.attributes.position.count > 0) ids.add(key.split('/')[1]);
    return ids.size;
  }

  set_trajectory(xyz) {
    if (this.trajectory) {
      this.scene.remove(this.trajectory);
      this.trajectory.geometry.dispose();
    }
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(xyz.flat()), 3));
    this.trajectory = new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: 0x4da3ff }));
    this.scene.add(this.trajectory);
    this.render();
  }

  set_pose(T_world_cam) {
    this.pose.visible = T_world_cam != null;
    if (T_world_cam) this.pose.matrix.copy(matrix_from_rows(T_world_cam));
    this.render();
  }

  // Boxes (centre, size, quaternion w x y z) and seam polylines, coloured by state.
  set_detections(detections) {
    for (const child of [...this.regions.children]) {
      this.regions.remove(child);
      child.geometry.dispose();
      child.material.dispose();
    }
    const unit_box = new THREE.EdgesGeometry(new THREE.BoxGeometry(1, 1, 1));
    for (const d of detections) {
      const colour = STATE_COLOURS[d.state] ?? 0xffffff;
      const box = new THREE.LineSegments(unit_box.clone(), new THREE.LineBasicMaterial({ color: colour }));
      box.position.fromArray(d.center_world_m);
      box.scale.set(...d.size_m.map((v) => Math.max(v, 1e-3)));
      const [w, x, y, z] = d.q_world_box;
      box.quaternion.set(x, y, z, w);
      this.regions.add(box);
      if (d.seam_world_m.length >= 2) {
        const seam = new THREE.BufferGeometry();
        seam.setAttribute('position', new THREE.BufferAttribute(new Float32Array(d.seam_world_m.flat()), 3));
        this.regions.add(new THREE.Line(seam, new THREE.LineBasicMaterial({ color: 0xff66ff })));
      }
    }
    unit_box.dispose();
    this.render();
  }

  frame_sphere(sphere) {
    const r = Math.max(sphere.radius, 0.5);
    const c = sphere.center;
    this.controls.target.copy(c);
    this.camera.position.set(c.x - 1.2 * r, c.y - 1.2 * r, c.z + 1.0 * r);
    this.controls.update();
    this.render();
  }

  // Everything drawn: segments, trajectory, pose and regions.
  frame_all() {
    const box = new THREE.Box3();
    for (const s of this.segments.values()) box.expandByObject(s.points);
    if (this.trajectory) box.expandByObject(this.trajectory);
    box.expandByObject(this.regions);
    if (this.pose.visible) box.expandByPoint(new THREE.Vector3().setFromMatrixPosition(this.pose.matrix));
    if (!box.isEmpty()) this.frame_sphere(box.getBoundingSphere(new THREE.Sphere()));
  }

  frame_detection(d) {
    this.operator_moved = true;
    const size = Math.max(...d.size_m, 0.2);
    this.frame_sphere(new THREE.Sphere(new THREE.Vector3().fromArray(d.center_world_m), 2 * size));
  }
}
