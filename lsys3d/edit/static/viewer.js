// lsys3d's 3D viewer: a .glb written by lsys3d.exchange, shown with three.js (vendor/three, MIT).
// Used by the editor's page (app.js) and, inlined, by Tree._repr_html_ in notebooks (lsys3d/edit/notebook.py).
// Views: shaded, wireframe, skeleton (the branch curves), UV checker; leaves on/off; level of detail;
// a ground grid in metres; orbit with the mouse. Renders only when something changed.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

const VIEWS = ['shaded', 'wireframe', 'skeleton', 'uv'];

function checkerTexture() {
  const canvas = document.createElement('canvas');
  canvas.width = canvas.height = 256;
  const g = canvas.getContext('2d');
  for (let y = 0; y < 8; y++) {
    for (let x = 0; x < 8; x++) {
      g.fillStyle = (x + y) % 2 ? '#e8e8e8' : '#d0402a';
      g.fillRect(x * 32, y * 32, 32, 32);
    }
  }
  g.fillStyle = '#204080';
  g.font = 'bold 20px sans-serif';
  for (let y = 0; y < 8; y += 2) for (let x = 0; x < 8; x += 2) g.fillText(`${x / 2}${y / 2}`, x * 32 + 4, y * 32 + 22);
  const texture = new THREE.CanvasTexture(canvas);
  texture.wrapS = texture.wrapT = THREE.RepeatWrapping;
  texture.colorSpace = THREE.SRGBColorSpace;
  return texture;
}

function isLeaf(object) {
  // the writer's node names: "leaf", "leaf_polygons", "organ_<name>" (docs/export.md)
  let o = object;
  while (o) {
    if (o.name === 'leaf' || o.name === 'leaf_polygons' || o.name.startsWith('organ_')) return true;
    o = o.parent;
  }
  return false;
}

function isSkeleton(object) {
  let o = object;
  while (o) {
    if (o.name === 'skeleton') return true;
    o = o.parent;
  }
  return false;
}

export function createViewer(container, options = {}) {
  const root = document.createElement('div');
  root.className = 'lsys3d-viewer';
  root.style.cssText = 'position:relative;width:100%;height:100%;min-height:240px;background:#1d2127;overflow:hidden';
  container.appendChild(root);
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  renderer.domElement.style.cssText = 'display:block;width:100%;height:100%';
  renderer.domElement.dataset.testid = 'viewport';
  root.appendChild(renderer.domElement);

  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1d2127);
  const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
  camera.position.set(4, 3, 6);
  scene.add(new THREE.HemisphereLight(0xdfe8ff, 0x3a3326, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 2.2);
  sun.position.set(5, 10, 7);
  scene.add(sun);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.enableDamping = false;

  const state = {
    view: options.view || 'shaded',
    leaves: true,
    lod: 0,
    model: null, // the scene of the glb shown
    levels: [], // [level, Object3D] of the glb's levels of detail (level 0: the scene)
    shown: null, // the object in the scene: model or a level
    skeleton: null, // the last "skeleton" lines seen (the soup carries them; the union may not)
    grid: null,
    gridCell: 1,
    framed: false,
    triangles: 0,
    loads: 0,
  };
  const checker = checkerTexture();
  const originals = new Map();
  const listeners = [];

  // ---------------------------------------------------------------- toolbar
  const bar = document.createElement('div');
  bar.className = 'lsys3d-viewer-bar';
  bar.style.cssText =
    'position:absolute;left:6px;top:6px;display:flex;gap:6px;align-items:center;font:12px sans-serif;color:#ddd;' +
    'background:rgba(20,22,26,.75);padding:4px 6px;border-radius:4px';
  const viewSelect = document.createElement('select');
  viewSelect.dataset.testid = 'view';
  for (const v of VIEWS) viewSelect.add(new Option({ uv: 'UV checker' }[v] || v, v));
  viewSelect.value = state.view;
  const leavesBox = document.createElement('input');
  leavesBox.type = 'checkbox';
  leavesBox.checked = true;
  leavesBox.dataset.testid = 'leaves';
  const leavesLabel = document.createElement('label');
  leavesLabel.append(leavesBox, ' leaves');
  const lodSelect = document.createElement('select');
  lodSelect.dataset.testid = 'lod';
  lodSelect.title = 'level of detail';
  lodSelect.add(new Option('LOD0', '0'));
  const info = document.createElement('span');
  info.dataset.testid = 'triangles';
  bar.append(viewSelect, leavesLabel, lodSelect, info);
  if (options.toolbar !== false) root.appendChild(bar);
  viewSelect.onchange = () => api.setView(viewSelect.value);
  leavesBox.onchange = () => api.setLeaves(leavesBox.checked);
  lodSelect.onchange = () => api.setLod(Number(lodSelect.value));

  // ---------------------------------------------------------------- drawing
  let pending = false;
  function render() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => {
      pending = false;
      renderer.render(scene, camera);
    });
  }
  controls.addEventListener('change', render);
  function resize() {
    const w = root.clientWidth || 400;
    const h = root.clientHeight || 300;
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
    render();
  }
  new ResizeObserver(resize).observe(root);

  function countTriangles() {
    let n = 0;
    if (!state.shown) return 0;
    state.shown.traverseVisible((o) => {
      if (!o.isMesh || !o.geometry) return;
      const g = o.geometry;
      const count = g.index ? g.index.count : g.attributes.position ? g.attributes.position.count : 0;
      n += (count / 3) * (o.isInstancedMesh ? o.count : 1);
    });
    return Math.round(n);
  }

  function material(mesh) {
    if (!originals.has(mesh)) originals.set(mesh, mesh.material);
    const base = originals.get(mesh);
    if (state.view === 'wireframe') {
      const m = base.clone();
      m.wireframe = true;
      return m;
    }
    if (state.view === 'uv' && !isLeaf(mesh)) {
      return new THREE.MeshStandardMaterial({ map: checker, roughness: 0.8, side: base.side });
    }
    if (state.view === 'skeleton') {
      return new THREE.MeshStandardMaterial({ color: 0x8a7a66, transparent: true, opacity: 0.18, depthWrite: false });
    }
    return base;
  }

  function apply() {
    if (!state.shown) return;
    state.shown.traverse((o) => {
      if (isSkeleton(o)) {
        o.visible = false; // the skeleton is drawn from state.skeleton
        return;
      }
      if (o.isMesh) {
        const previous = o.material;
        o.material = material(o);
        if (previous !== o.material && previous !== originals.get(o)) previous.dispose();
        o.visible = state.leaves || !isLeaf(o);
      }
    });
    if (state.skeleton) state.skeleton.visible = state.view === 'skeleton';
    state.triangles = countTriangles();
    info.textContent = `${state.triangles.toLocaleString('en')} triangles · grid ${state.gridCell} m`;
    root.dataset.triangles = String(state.triangles);
    render();
  }

  function ground(box) {
    if (state.grid) {
      scene.remove(state.grid);
      state.grid.geometry.dispose();
    }
    const size = box.getSize(new THREE.Vector3());
    const extent = Math.max(size.x, size.z, size.y * 0.6, 0.01);
    const cell = extent > 4 ? 1 : extent > 0.4 ? 0.1 : 0.01;
    const half = Math.ceil((extent * 0.9) / cell) * cell;
    const divisions = Math.max(2, Math.round((2 * half) / cell));
    state.grid = new THREE.GridHelper(2 * half, divisions, 0x66707c, 0x3a4048);
    state.grid.position.set(0, box.min.y < 0 ? box.min.y : 0, 0);
    state.gridCell = cell;
    scene.add(state.grid);
  }

  function frame(box) {
    const size = box.getSize(new THREE.Vector3());
    const center = box.getCenter(new THREE.Vector3());
    const radius = Math.max(size.length() / 2, 0.01);
    const distance = radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2));
    camera.near = distance / 100;
    camera.far = distance * 100;
    camera.position.copy(center).add(new THREE.Vector3(0.55, 0.35, 1).normalize().multiplyScalar(distance));
    camera.updateProjectionMatrix();
    controls.target.copy(center);
    controls.update();
  }

  function show(object) {
    if (state.shown) scene.remove(state.shown);
    state.shown = object;
    scene.add(object);
    apply();
  }

  const loader = new GLTFLoader();
  if (options.headers) loader.setRequestHeader(options.headers);

  const api = {
    THREE,
    renderer,
    scene,
    camera,
    get triangles() {
      return state.triangles;
    },
    get loads() {
      return state.loads;
    },
    /** The shown tree's bounding box, [[x, y, z], [x, y, z]] in metres. */
    bounds() {
      if (!state.shown) return null;
      const box = new THREE.Box3().setFromObject(state.shown);
      return [box.min.toArray(), box.max.toArray()];
    },
    /** Show the .glb in `data` (an ArrayBuffer); keeps the camera unless `frame` or the first one. */
    async load(data, { frame: refit = false } = {}) {
      const gltf = await loader.parseAsync(data, '');
      for (const [mesh, m] of originals) if (m !== mesh.material) mesh.material.dispose?.();
      originals.clear();
      if (state.model) {
        state.model.traverse((o) => {
          if (o.geometry) o.geometry.dispose();
        });
      }
      state.model = gltf.scene;
      let lines = null;
      gltf.scene.traverse((o) => {
        if (o.name === 'skeleton' && !lines) lines = o;
      });
      if (lines) {
        if (state.skeleton) scene.remove(state.skeleton);
        state.skeleton = lines.clone();
        state.skeleton.traverse((o) => {
          if (o.material) o.material = new THREE.LineBasicMaterial({ color: 0xffd27a });
        });
        const world = new THREE.Matrix4();
        lines.updateWorldMatrix(true, false);
        world.copy(lines.matrixWorld);
        state.skeleton.matrixAutoUpdate = false;
        state.skeleton.matrix.copy(world);
        scene.add(state.skeleton);
      }
      // levels of detail: nodes named <asset>_LOD<k> (MSFT_lod, outside the scene)
      state.levels = [[0, gltf.scene]];
      const nodes = gltf.parser.json.nodes || [];
      for (let i = 0; i < nodes.length; i++) {
        const m = /_LOD(\d+)$/.exec(nodes[i].name || '');
        if (m && Number(m[1]) > 0) state.levels.push([Number(m[1]), await gltf.parser.getDependency('node', i)]);
      }
      lodSelect.innerHTML = '';
      for (const [level] of state.levels) lodSelect.add(new Option(`LOD${level}`, String(level)));
      if (!state.levels.some(([level]) => level === state.lod)) state.lod = 0;
      lodSelect.value = String(state.lod);
      const box = new THREE.Box3().setFromObject(gltf.scene);
      if (box.isEmpty()) box.set(new THREE.Vector3(-1, 0, -1), new THREE.Vector3(1, 1, 1));
      ground(box);
      if (refit || !state.framed) {
        frame(box);
        state.framed = true;
      }
      show(state.levels.find(([level]) => level === state.lod)[1]);
      state.loads += 1;
      root.dataset.loads = String(state.loads);
      for (const f of listeners) f(api);
      return { triangles: state.triangles, levels: state.levels.map(([l]) => l) };
    },
    setView(view) {
      if (!VIEWS.includes(view)) throw new Error(`unknown view ${view}`);
      state.view = view;
      viewSelect.value = view;
      apply();
    },
    setLeaves(on) {
      state.leaves = Boolean(on);
      leavesBox.checked = state.leaves;
      apply();
    },
    setLod(level) {
      const found = state.levels.find(([l]) => l === level);
      if (!found) return;
      state.lod = level;
      lodSelect.value = String(level);
      show(found[1]);
    },
    frame() {
      if (state.model) frame(new THREE.Box3().setFromObject(state.model));
      render();
    },
    onLoad(f) {
      listeners.push(f);
    },
    /** A picture of what is shown, `w` x `h` pixels, as a data URL (the page's strip of seed variants). */
    picture(w = 160, h = 160) {
      renderer.render(scene, camera);
      const canvas = document.createElement('canvas');
      canvas.width = w;
      canvas.height = h;
      const src = renderer.domElement;
      const s = Math.min(src.width, src.height);
      canvas.getContext('2d').drawImage(src, (src.width - s) / 2, (src.height - s) / 2, s, s, 0, 0, w, h);
      return canvas.toDataURL('image/png');
    },
  };
  resize();
  return api;
}
