// The job page's 3D view: a snapshot's cells as shaded surfaces (three.js r111 from Debian's
// libjs-three, served by foamd as three.js and orbit-controls.js), loaded from foamd's binary
// route jobs/ID/snapshots/N.mesh (its layout: server/mesh_frame.h). app.js creates one per job
// page and hands it the job's snapshot list on every refresh.
'use strict';

const View3D = (() => {
  const BACKGROUND = 0xf4f6f9;
  const SPHEROID_COLORS = ['#1c6bb0', '#e8590c'];  // A, B: the dashboard's first two colours
  const PLAY_MS = 700;       // least time a frame stays up while playing
  const CACHE_FRAMES = 24;   // decoded snapshots kept: scrubbing back and forth refetches nothing

  // Why the view cannot be shown here, or '' when it can.
  function unavailable() {
    if (window.FOAMD_NO_THREE) return window.FOAMD_NO_THREE;
    // OrbitControls makes an empty THREE of its own when three.js is missing.
    if (typeof THREE === 'undefined' || typeof THREE.WebGLRenderer !== 'function') return 'three.js did not load';
    if (typeof THREE.OrbitControls !== 'function') return 'three.js OrbitControls did not load';
    return '';
  }

  function parseMesh(buffer) {
    const bytes = new Uint8Array(buffer);
    if (bytes.length < 8 || String.fromCharCode(...bytes.subarray(0, 4)) !== 'AFM1')
      throw new Error('not an activefoam mesh (AFM1)');
    const n = new DataView(buffer).getUint32(4, true);
    const header = JSON.parse(new TextDecoder().decode(bytes.subarray(8, 8 + n)));
    // Typed arrays read in the machine's byte order; the route writes little-endian, which is
    // every platform a browser runs on.
    return {
      header,
      positions: new Float32Array(buffer, header.positions_offset, 3 * header.vertices),
      triangles: new Uint32Array(buffer, header.triangles_offset, 3 * header.triangles),
    };
  }

  // Each cell's enclosed volume (µm³) from its closed surface (divergence theorem).
  function cellVolumes(mesh) {
    const {header, positions: p, triangles: t} = mesh;
    const out = new Float64Array(header.cells);
    for (let c = 0; c < header.cells; c++) {
      let v = 0;
      for (let k = 3 * header.triangle_start[c]; k < 3 * header.triangle_start[c + 1]; k += 3) {
        const a = 3 * t[k], b = 3 * t[k + 1], d = 3 * t[k + 2];
        v += p[a] * (p[b + 1] * p[d + 2] - p[b + 2] * p[d + 1])
          - p[a + 1] * (p[b] * p[d + 2] - p[b + 2] * p[d])
          + p[a + 2] * (p[b] * p[d + 1] - p[b + 1] * p[d]);
      }
      out[c] = v / 6;
    }
    return out;
  }

  // A perceptually ordered ramp (viridis' end points and middle), t in [0, 1].
  const RAMP = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
  function ramp(t) {
    const x = Math.min(1, Math.max(0, Number.isFinite(t) ? t : 0)) * (RAMP.length - 1);
    const i = Math.min(RAMP.length - 2, Math.floor(x)), f = x - i;
    return RAMP[i].map((c, k) => (c + (RAMP[i + 1][k] - c) * f) / 255);
  }
  const rampCss = () => `linear-gradient(to right, ${RAMP.map(c => `rgb(${c})`).join(', ')})`;

  // Per-cell colours [r, g, b] in 0..1 and the legend that explains them.
  function cellColors(mesh, mode) {
    const h = mesh.header;
    const rgb = css => {
      const c = new THREE.Color(css);
      return [c.r, c.g, c.b];
    };
    if (mode === 'cell') {
      // The golden angle spreads neighbouring ids' hues apart.
      const colors = h.cell_id.map(id => {
        const c = new THREE.Color().setHSL((id * 0.618034) % 1, 0.55, 0.55);
        return [c.r, c.g, c.b];
      });
      return {colors, legend: {kind: 'text', text: `${h.cells} cells, one colour each`}};
    }
    if (mode === 'pressure' || mode === 'volume') {
      const values = mode === 'pressure' ? h.pressure_kPa || [] : Array.from(cellVolumes(mesh));
      const finite = values.filter(Number.isFinite);
      const lo = finite.length ? Math.min(...finite) : 0, hi = finite.length ? Math.max(...finite) : 1;
      const colors = h.cell_id.map((_, c) => ramp(hi > lo ? (values[c] - lo) / (hi - lo) : 0.5));
      const unit = mode === 'pressure' ? 'kPa' : 'µm³';
      return {colors, legend: {kind: 'ramp', label: mode === 'pressure' ? 'pressure P' : 'cell volume', lo, hi, unit}};
    }
    const labels = new Set(h.spheroid);
    const colors = h.spheroid.map(l => rgb(SPHEROID_COLORS[l === 1 ? 1 : 0]));
    return {colors, legend: {kind: 'spheroids', both: labels.has(1) && labels.size > 1}};
  }

  // The fusion axis: the line through the two spheroids' centroids; x through the centroid of
  // everything where there is one spheroid.
  function fusionAxis(mesh) {
    const {header: h, positions: p} = mesh;
    const sum = [new THREE.Vector3(), new THREE.Vector3()], n = [0, 0];
    for (let c = 0; c < h.cells; c++) {
      const s = h.spheroid[c] === 1 ? 1 : 0;
      for (let v = h.vertex_start[c]; v < h.vertex_start[c + 1]; v++) {
        sum[s].x += p[3 * v];
        sum[s].y += p[3 * v + 1];
        sum[s].z += p[3 * v + 2];
        n[s]++;
      }
    }
    if (n[0] && n[1]) {
      const a = sum[0].divideScalar(n[0]), b = sum[1].divideScalar(n[1]);
      const dir = b.clone().sub(a);
      if (dir.lengthSq() > 0) return {center: a.clone().add(b).multiplyScalar(0.5), dir: dir.normalize()};
    }
    const all = sum[0].add(sum[1]).divideScalar(Math.max(1, n[0] + n[1]));
    return {center: all, dir: new THREE.Vector3(1, 0, 0)};
  }

  // How far back a camera looking (nearly) along -z must stand for the box to fill the view
  // with a margin: its x extent across the width, its y and z extents as the 19° tilt projects
  // them up the height. render.cc's frameBox computes the same for the movies.
  function frameDistance(b, fovDeg, aspect) {
    const tan = Math.tan((fovDeg * Math.PI) / 360);
    const rx = Math.max(0.5, (b[3] - b[0]) / 2), ry = Math.max(0.5, (b[4] - b[1]) / 2), rz = (b[5] - b[2]) / 2;
    return 1.1 * Math.max((0.95 * ry + 0.35 * rz) / tan, rx / (tan * aspect)) + rz;
  }

  const contains = (outer, b) => [0, 1, 2].every(d => b[d] >= outer[d] && b[d + 3] <= outer[d + 3]);
  const union = (a, b) => [0, 1, 2, 3, 4, 5].map(d => (d < 3 ? Math.min(a[d], b[d]) : Math.max(a[d], b[d])));

  class View {
    // root: the figure of tpl-job holding the canvas and controls; fetchBuffer(path) resolves
    // to an ArrayBuffer (with the token), rejecting with app.js's errors.
    constructor(root, jobId, fetchBuffer, onError) {
      this.root = root;
      this.jobId = jobId;
      this.fetchBuffer = fetchBuffer;
      this.onError = onError;
      this.canvas = root.querySelector('canvas');
      this.slider = root.querySelector('.view3d-slider');
      this.playButton = root.querySelector('.view3d-play');
      this.timeLabel = root.querySelector('.view3d-time');
      this.message = root.querySelector('.view3d-message');
      this.legend = root.querySelector('.view3d-legend');
      this.colorSelect = root.querySelector('.view3d-color');
      this.clipBox = root.querySelector('.view3d-clip');
      this.snaps = [];
      this.cache = new Map();     // snapshot index -> parsed mesh, oldest first
      this.shown = null;          // the parsed mesh on screen
      this.wanted = -1;           // the snapshot index last asked for
      this.following = true;      // the slider sits on the newest snapshot and stays there
      this.playing = false;
      this.framedBox = null;      // the bounds the camera was placed for
      this.userMoved = false;     // orbited, zoomed or panned: the camera is the user's

      const why = unavailable();
      if (why) {
        this.disable(`No 3D view: ${why}.`);
        return;
      }
      try {
        this.renderer = new THREE.WebGLRenderer({canvas: this.canvas, antialias: true,
          preserveDrawingBuffer: true});  // so that the picture can be read back (tests, saving)
      } catch (e) {
        this.disable(`No 3D view: this browser cannot create a WebGL context (${e.message}).`);
        return;
      }
      this.renderer.setPixelRatio(window.devicePixelRatio || 1);
      this.renderer.setClearColor(BACKGROUND);
      this.renderer.localClippingEnabled = true;
      this.scene = new THREE.Scene();
      this.camera = new THREE.PerspectiveCamera(30, 1, 0.1, 1e5);
      this.scene.add(this.camera);
      this.scene.add(new THREE.AmbientLight(0xffffff, 0.42));
      const light = new THREE.DirectionalLight(0xffffff, 0.72);
      // A head light from over the viewer's shoulder, wherever the view orbits: light and
      // target both ride on the camera (a target left in the scene would aim it at the origin).
      light.position.set(0.4, 0.6, 1);
      this.camera.add(light, light.target);
      this.clipPlane = new THREE.Plane(new THREE.Vector3(0, 0, -1), 0);
      this.material = new THREE.MeshLambertMaterial({vertexColors: THREE.VertexColors,
        side: THREE.DoubleSide, clippingPlanes: []});
      this.geometry = new THREE.BufferGeometry();
      this.mesh = new THREE.Mesh(this.geometry, this.material);
      this.mesh.name = 'cells';
      this.scene.add(this.mesh);
      this.controls = new THREE.OrbitControls(this.camera, this.canvas);
      // r111's controls listen for arrow keys on the whole window: they would pan the view while
      // the slider (or a text field) takes the same keys.
      this.controls.enableKeys = false;
      this.controls.addEventListener('change', () => this.render());
      this.controls.addEventListener('start', () => (this.userMoved = true));
      this.canvas.dataset.state = 'empty';

      this.slider.addEventListener('input', () => {
        this.stop();
        this.following = Number(this.slider.value) === this.snaps.length - 1;
        this.show(Number(this.slider.value));
      });
      this.playButton.addEventListener('click', () => (this.playing ? this.stop() : this.play()));
      this.colorSelect.addEventListener('change', () => this.recolor());
      this.clipBox.addEventListener('change', () => this.render());
      this.onResize = () => this.resize();
      window.addEventListener('resize', this.onResize);
      this.resize();
    }

    disable(text) {
      this.canvas.dataset.state = 'unavailable';
      this.message.textContent = text;
      this.message.hidden = false;
      this.root.querySelectorAll('button, input, select').forEach(x => (x.disabled = true));
    }

    get usable() {
      return Boolean(this.renderer);
    }

    // The job's snapshot list (GetResults' snapshots: index, t_s, ...), as of this refresh.
    setSnapshots(snaps) {
      if (!this.usable) return;
      // By the newest index, not the count: with keep_snapshots foamd drops the oldest as new
      // ones come, and the count stays put.
      const newest = snaps.length ? snaps[snaps.length - 1].index : -1;
      const grew = newest !== (this.snaps.length ? this.snaps[this.snaps.length - 1].index : -1);
      this.snaps = snaps;
      this.slider.max = String(Math.max(0, snaps.length - 1));
      this.slider.disabled = snaps.length < 2;
      this.playButton.disabled = snaps.length < 2;
      if (!snaps.length) {
        this.message.textContent = 'No snapshots yet (the spec\'s snapshot_every_s sets how often they are taken).';
        this.message.hidden = false;
        return;
      }
      if (this.following && (grew || this.wanted < 0)) this.show(snaps.length - 1);
      else this.updateLabel();
    }

    // Shows the k-th snapshot of the list, fetching it unless it is cached.
    async show(k) {
      const info = this.snaps[k];
      if (!info) return;
      this.slider.value = String(k);
      this.wanted = info.index;
      this.updateLabel();
      let mesh = this.cache.get(info.index);
      if (!mesh) {
        this.canvas.dataset.state = 'loading';
        try {
          const buffer = await this.fetchBuffer(`jobs/${encodeURIComponent(this.jobId)}/snapshots/${info.index}.mesh`);
          mesh = parseMesh(buffer);
        } catch (e) {
          if (this.wanted === info.index) {
            this.canvas.dataset.state = 'error';
            this.stop();
            this.onError(e);
          }
          return;
        }
        this.cache.set(info.index, mesh);
        if (this.cache.size > CACHE_FRAMES) this.cache.delete(this.cache.keys().next().value);
      }
      if (this.wanted !== info.index || !this.renderer) return;  // a newer request, or the page is gone
      this.setMesh(mesh);
    }

    setMesh(mesh) {
      const h = mesh.header;
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(mesh.positions, 3));
      g.setIndex(new THREE.BufferAttribute(mesh.triangles, 1));
      g.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * h.vertices), 3));
      g.computeVertexNormals();
      this.mesh.geometry = g;
      this.geometry.dispose();
      this.geometry = g;
      this.shown = mesh;
      this.axis = fusionAxis(mesh);
      // Until the user moves the camera, it widens to every frame seen (the first snapshot of
      // a fusion spans more than the last, which a finished job's page shows first).
      if (!this.framedBox) this.frame(h.bounds);
      else if (!this.userMoved && !contains(this.framedBox, h.bounds)) this.frame(union(this.framedBox, h.bounds));
      this.recolor();
      this.message.hidden = true;
      this.canvas.dataset.snapshot = String(h.index);
      this.canvas.dataset.triangles = String(h.triangles);
      this.canvas.dataset.state = 'ready';
    }

    // A camera looking across the fusion axis at the whole first frame; kept for later frames,
    // so that the tissue moves and the viewpoint does not.
    frame(b) {
      const center = new THREE.Vector3((b[0] + b[3]) / 2, (b[1] + b[4]) / 2, (b[2] + b[5]) / 2);
      const distance = frameDistance(b, this.camera.fov, this.camera.aspect);
      this.camera.position.copy(center).add(new THREE.Vector3(0, -0.35, 1).normalize().multiplyScalar(distance));
      this.camera.near = distance / 100;
      this.camera.far = distance * 10;
      this.camera.updateProjectionMatrix();
      this.controls.target.copy(center);
      this.controls.update();
      this.framedBox = b;
    }

    recolor() {
      const mesh = this.shown;
      if (!mesh) return;
      const h = mesh.header;
      const {colors, legend} = cellColors(mesh, this.colorSelect.value);
      const attr = this.geometry.getAttribute('color');
      for (let c = 0; c < h.cells; c++) {
        const [r, g, b] = colors[c];
        for (let v = h.vertex_start[c]; v < h.vertex_start[c + 1]; v++) attr.setXYZ(v, r, g, b);
      }
      attr.needsUpdate = true;
      this.drawLegend(legend);
      this.render();
    }

    drawLegend(legend) {
      const swatch = color => el('span', {class: 'swatch', style: `background:${color}`});
      if (legend.kind === 'spheroids') {
        this.legend.replaceChildren(swatch(SPHEROID_COLORS[0]), 'spheroid A',
          ...(legend.both ? [swatch(SPHEROID_COLORS[1]), 'spheroid B'] : []));
      } else if (legend.kind === 'ramp') {
        this.legend.replaceChildren(`${legend.label}: ${formatNumber(legend.lo)}`,
          el('span', {class: 'ramp', style: `background:${rampCss()}`}), `${formatNumber(legend.hi)} ${legend.unit}`);
      } else {
        this.legend.replaceChildren(legend.text);
      }
    }

    updateLabel() {
      const k = Number(this.slider.value), info = this.snaps[k];
      this.timeLabel.textContent = info
        ? `t = ${formatNumber(info.t_s)} s · snapshot ${k + 1} of ${this.snaps.length}${this.following && this.snaps.length > 1 ? ' (latest)' : ''}`
        : '';
    }

    play() {
      if (this.snaps.length < 2) return;
      this.playing = true;
      this.playButton.textContent = 'Pause';
      let k = Number(this.slider.value);
      if (k >= this.snaps.length - 1) k = -1;
      const step = async () => {
        if (!this.playing) return;
        k++;
        if (k >= this.snaps.length) {
          this.stop();
          return;
        }
        this.following = k === this.snaps.length - 1;
        const started = performance.now();
        await this.show(k);
        const wait = Math.max(0, PLAY_MS - (performance.now() - started));
        if (this.playing) this.playTimer = setTimeout(step, wait);
      };
      step();
    }

    stop() {
      this.playing = false;
      clearTimeout(this.playTimer);
      if (this.playButton) this.playButton.textContent = 'Play';
    }

    resize() {
      if (!this.renderer) return;
      const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
      if (!w || !h) return;
      this.renderer.setSize(w, h, false);
      this.camera.aspect = w / h;
      this.camera.updateProjectionMatrix();
      this.render();
    }

    // The clip plane holds the fusion axis and faces the camera: the near halves of both
    // spheroids are cut away wherever the view orbits, and the interface shows in section.
    updateClip() {
      if (!this.clipBox.checked || !this.axis) {
        this.material.clippingPlanes = [];
        return;
      }
      const {center, dir} = this.axis;
      const toCamera = this.camera.position.clone().sub(center);
      const n = toCamera.sub(dir.clone().multiplyScalar(toCamera.dot(dir)));
      if (n.lengthSq() < 1e-12) {  // looking along the axis: any plane holding it will do
        n.set(dir.y, -dir.x, 0);
        if (n.lengthSq() < 1e-12) n.set(0, 1, 0);
      }
      n.normalize().negate();  // three.js keeps what is in front of the plane's normal
      this.clipPlane.setFromNormalAndCoplanarPoint(n, center);
      this.material.clippingPlanes = [this.clipPlane];
    }

    render() {
      if (!this.renderer || this.frameRequested) return;
      this.frameRequested = true;
      requestAnimationFrame(() => {
        this.frameRequested = false;
        if (!this.renderer) return;
        this.updateClip();
        this.renderer.render(this.scene, this.camera);
        this.canvas.dataset.renders = String(Number(this.canvas.dataset.renders || 0) + 1);
      });
    }

    destroy() {
      this.stop();
      window.removeEventListener('resize', this.onResize);
      if (!this.renderer) return;
      this.controls.dispose();
      this.geometry.dispose();
      this.material.dispose();
      this.renderer.dispose();
      // Browsers keep a handful of WebGL contexts per page: free this one now, not at GC.
      this.renderer.forceContextLoss();
      this.renderer = null;
    }
  }

  return {View, unavailable, parseMesh};
})();
