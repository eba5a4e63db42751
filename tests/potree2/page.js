// The page the Potree 2 export test opens in headless Chromium: potree-core loads the dataset at
// ?base=URL/ (its metadata.json, hierarchy.bin and octree.bin), every node of it (no minimum
// node size, a budget above the dataset's points), looking down at the whole cloud; then it
// publishes what potree-core loaded in window.result for the driver to read.
import * as THREE from "three";
import { PointColorType, Potree } from "potree-core";

const base = new URLSearchParams(location.search).get("base");
const size = 512;
const canvas = document.createElement("canvas");
document.body.style.margin = "0";
document.body.appendChild(canvas);
// Opaque and kept, so the screenshot shows what was drawn. (potree-core 2.0.15 draws these
// points white on SwiftShader, as it does PotreeConverter 2's output of the same file; the
// test asserts coverage, not colour.)
const renderer = new THREE.WebGLRenderer({ canvas, alpha: false, preserveDrawingBuffer: true });
renderer.setSize(size, size);
renderer.setClearColor(0x000000, 1);
const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(60, 1, 0.1, 1e7);

async function main() {
  const potree = new Potree();
  potree.pointBudget = 50_000_000;
  const pco = await potree.loadPointCloud("metadata.json", base);
  pco.minNodePixelSize = 0;
  pco.material.size = 2;
  pco.material.pointColorType = PointColorType.RGB;
  scene.add(pco);
  // Above the points' centre (the position attribute's range, in the dataset's coordinates,
  // which are the scene's), looking down, far enough to see all of them.
  const meta = await (await fetch(base + "metadata.json")).json();
  const position = meta.attributes.find((a) => a.name === "position");
  const box = new THREE.Box3(new THREE.Vector3(...position.min), new THREE.Vector3(...position.max));
  const centre = box.getCenter(new THREE.Vector3());
  const extent = box.getSize(new THREE.Vector3());
  const reach = Math.max(extent.x, extent.y, extent.z);
  camera.position.set(centre.x, centre.y - 0.3 * reach, centre.z + 1.6 * reach);
  camera.up.set(0, 0, 1);
  camera.lookAt(centre);
  camera.near = reach / 1000;
  camera.far = reach * 10;
  camera.updateProjectionMatrix();
  let last = -1, steady = 0, frames = 0, update = null;
  // Until the loaded points stop changing for a while (nodes arrive asynchronously).
  while (steady < 30 && frames < 3000) {
    update = potree.updatePointClouds([pco], camera, renderer);
    renderer.render(scene, camera);
    await new Promise((r) => requestAnimationFrame(r));
    const loading = pco.pcoGeometry.numNodesLoading;
    steady = update.numVisiblePoints === last && loading === 0 ? steady + 1 : 0;
    last = update.numVisiblePoints;
    frames++;
  }
  window.result = {
    points: update.numVisiblePoints,
    nodes: update.visibleNodes.length,
    names: update.visibleNodes.map((n) => n.geometryNode.name),
    declared: meta.points,
    frames,
  };
}
main().catch((e) => {
  window.result = { error: String(e && e.stack ? e.stack : e) };
});
