// netsim replay: draws a run at the cursor from the arrays packed by netsim/tools/viewer/data.py.
// Per frame the work is O(N + links up + changes since the last frame): positions come
// from each robot's current leg, roles and links from sweeps over their change events.
"use strict";
(function () {
  const META = JSON.parse(document.getElementById("netsim-meta").textContent);
  const PAL = META.palette;
  const ROLE_NAMES = ["gamma", "beta", "alpha"];
  const GAMMA = 0, BETA = 1, ALPHA = 2;
  // Every colour, marker and size comes from META.palette (netsim/tools/style.py), as in
  // the figures: none is named here.
  const GROUPS = PAL.group_palette;
  const LINE_MARKERS = new Set(["x", "+"]); // drawn as strokes in the fill colour
  // A run without the clustering protocol has no roles: its robots are plain dots.
  const NO_ROLES = !META.has.roles;
  const view = (window.netsimView = { ready: false, error: null });

  const CTORS = { f64: Float64Array, f32: Float32Array, i32: Int32Array, i16: Int16Array, u16: Uint16Array, u8: Uint8Array, i8: Int8Array };

  async function decode() {
    const text = document.getElementById("netsim-blob").textContent.trim();
    const bin = atob(text);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
    const buf = await new Response(stream).arrayBuffer();
    const A = {};
    for (const [name, [code, offset, length]] of Object.entries(META.arrays)) A[name] = new CTORS[code](buf, offset, length);
    return A;
  }

  // Index of the last element <= t in a sorted array (-1 if none).
  function lastAtOrBefore(arr, t, lo = 0, hi = arr.length) {
    while (lo < hi) {
      const mid = (lo + hi) >> 1;
      if (arr[mid] <= t) lo = mid + 1;
      else hi = mid;
    }
    return lo - 1;
  }

  // The nearest image of an offset on a torus of side `side`, as the engine takes it
  // (numpy's rint: a half rounds to even, where Math.round rounds it up), so that a link
  // exactly half a side long is drawn the way the tables measure it.
  function nearestImage(d, side) {
    const q = d / side;
    let k = Math.round(q);
    if (k - q === 0.5 && k % 2 !== 0) k -= 1;
    return d - side * k;
  }

  // A coordinate folded into [0, side), as the engine folds it (a tiny negative one that
  // rounds up to the side itself is 0).
  function wrap(v, side) {
    const w = v % side;
    const r = w < 0 ? w + side : w;
    return r >= side ? r - side : r;
  }
  // The torus's laws, for the tests to compare with the engine's.
  view.torusLaws = { nearestImage, wrap };

  // ---------------------------------------------------------------- the run at time t
  class Model {
    constructor(A) {
      this.A = A;
      const n = (this.n = META.n);
      this.side = META.side_m;
      this.torus = META.torus;
      this.x = new Float64Array(n);
      this.y = new Float64Array(n);
      this.t = NaN;
      if (META.motion === "legs") {
        this.legCur = new Int32Array(n);
        for (let i = 0; i < n; i++) this.legCur[i] = A.legs_first[i];
      }
      this.role = new Int8Array(n);
      this.leader = new Int32Array(n).fill(-1);
      this.rolePtr = 0;
      const L = (this.nLinks = A.link_a.length);
      this.linkState = new Uint8Array(L);
      this.active = new Int32Array(L);
      this.activePos = new Int32Array(L).fill(-1);
      this.nActive = 0;
      this.downOrder = new Int32Array(L);
      for (let i = 0; i < L; i++) this.downOrder[i] = i;
      const down = A.link_down;
      this.downOrder.sort((a, b) => down[a] - down[b]);
      this.upPtr = 0;
      this.downPtr = 0;
      this.gateway = new Uint8Array(n);
      this.other = new Int32Array(n).fill(-1);
      this.groupSample = -1;
      this.parent = new Int32Array(n);
      this.degree = new Int32Array(n);
    }

    seek(t) {
      const back = !(t >= this.t);
      this.motion(t, back);
      this.roles(t, back);
      this.links(t, back);
      this.groups(t);
      this.t = t;
    }

    motion(t, back) {
      const A = this.A, n = this.n, x = this.x, y = this.y;
      if (META.motion === "legs") {
        const first = A.legs_first, lt = A.legs_t, cur = this.legCur;
        for (let i = 0; i < n; i++) {
          const end = first[i + 1];
          let k = cur[i];
          if (back) k = Math.max(first[i], lastAtOrBefore(lt, t, first[i], end));
          else while (k + 1 < end && lt[k + 1] <= t) k++;
          cur[i] = k;
          const dt = t - lt[k];
          x[i] = A.legs_x[k] + A.legs_vx[k] * dt;
          y[i] = A.legs_y[k] + A.legs_vy[k] * dt;
        }
      } else {
        const times = A.pos_t, xy = A.pos_xy, S = times.length;
        const k = Math.max(0, lastAtOrBefore(times, t));
        const k1 = Math.min(k + 1, S - 1);
        const f = k1 > k ? Math.min(1, Math.max(0, (t - times[k]) / (times[k1] - times[k]))) : 0;
        for (let i = 0; i < n; i++) {
          const a = 2 * (k * n + i), b = 2 * (k1 * n + i);
          let dx = xy[b] - xy[a], dy = xy[b + 1] - xy[a + 1];
          if (this.torus) {
            dx = nearestImage(dx, this.side);
            dy = nearestImage(dy, this.side);
          }
          x[i] = xy[a] + f * dx;
          y[i] = xy[a + 1] + f * dy;
        }
      }
      if (this.torus) {
        for (let i = 0; i < n; i++) {
          x[i] = wrap(x[i], this.side);
          y[i] = wrap(y[i], this.side);
        }
      }
    }

    roles(t, back) {
      const A = this.A;
      if (back) {
        this.role.fill(GAMMA);
        this.leader.fill(-1);
        this.rolePtr = 0;
      }
      const rt = A.role_t, R = rt.length;
      let p = this.rolePtr;
      while (p < R && rt[p] <= t) {
        const i = A.role_robot[p];
        this.role[i] = A.role_code[p];
        this.leader[i] = A.role_leader[p];
        p++;
      }
      this.rolePtr = p;
    }

    links(t, back) {
      const A = this.A, L = this.nLinks, state = this.linkState, pos = this.activePos, act = this.active;
      if (back) {
        state.fill(0);
        pos.fill(-1);
        this.nActive = 0;
        this.upPtr = 0;
        this.downPtr = 0;
      }
      const up = A.link_up, down = A.link_down, order = this.downOrder;
      while (this.upPtr < L && up[this.upPtr] <= t) {
        const i = this.upPtr++;
        state[i] |= 1;
        if (!(state[i] & 2)) {
          pos[i] = this.nActive;
          act[this.nActive++] = i;
        }
      }
      while (this.downPtr < L && down[order[this.downPtr]] <= t) {
        const i = order[this.downPtr++];
        state[i] |= 2;
        const p = pos[i];
        if (p >= 0) {
          const last = act[--this.nActive];
          act[p] = last;
          pos[last] = p;
          pos[i] = -1;
        }
      }
    }

    groups(t) {
      const A = this.A;
      this.gateway.fill(0);
      this.other.fill(-1);
      this.groupSample = -1;
      if (!META.has.groups) return;
      const k = lastAtOrBefore(A.grp_t, t);
      this.groupSample = k;
      if (k < 0) return;
      for (let r = A.grp_first[k]; r < A.grp_first[k + 1]; r++) {
        const i = A.grp_robot[r];
        this.gateway[i] = 1;
        // Rows ascend by group: the first other group is the lowest (style.other_group).
        if (!A.grp_primary[r] && this.other[i] < 0) this.other[i] = A.grp_group[r];
      }
    }

    // Groups of robot i at the last groups sample (its gateway memberships).
    groupsOf(i) {
      const A = this.A, k = this.groupSample, out = [];
      if (k < 0) return out;
      for (let r = A.grp_first[k]; r < A.grp_first[k + 1]; r++) if (A.grp_robot[r] === i) out.push(A.grp_group[r]);
      return out;
    }

    shape(i) {
      const r = this.role[i];
      if (r === BETA && this.gateway[i]) return "gateway";
      return ROLE_NAMES[r];
    }

    // Palette index of the group led by robot head (-1: none).
    colourOf(head) {
      return head >= 0 && head < this.n ? this.A.colour_of[head] : -1;
    }

    // Palette index of robot i's group (-1: none).
    colour(i) {
      const r = this.role[i];
      return this.colourOf(r === ALPHA ? i : r === BETA ? this.leader[i] : -1);
    }

    // Palette index of a gateway's other group (-1: none).
    edgeColour(i) {
      return this.colourOf(this.other[i]);
    }

    components() {
      const n = this.n, parent = this.parent, A = this.A;
      for (let i = 0; i < n; i++) parent[i] = i;
      const find = (i) => {
        while (parent[i] !== i) {
          parent[i] = parent[parent[i]];
          i = parent[i];
        }
        return i;
      };
      let count = n;
      for (let k = 0; k < this.nActive; k++) {
        const l = this.active[k];
        const a = find(A.link_a[l]), b = find(A.link_b[l]);
        if (a !== b) {
          parent[a] = b;
          count--;
        }
      }
      return count;
    }

    neighbours(i) {
      const A = this.A, out = [];
      for (let k = 0; k < this.nActive; k++) {
        const l = this.active[k];
        if (A.link_a[l] === i) out.push(A.link_b[l]);
        else if (A.link_b[l] === i) out.push(A.link_a[l]);
      }
      return out.sort((a, b) => a - b);
    }
  }

  // ---------------------------------------------------------------- drawing
  const field = document.getElementById("field");
  const ctx = field.getContext("2d");
  const chartCanvas = document.getElementById("chart");
  const chartCtx = chartCanvas.getContext("2d");
  const tip = document.getElementById("tip");
  const ui = {
    links: document.getElementById("show-links"),
    hops: document.getElementById("show-hops"),
    trail: document.getElementById("trail"),
    disks: document.getElementById("disks"),
    walls: document.getElementById("show-walls"),
    slider: document.getElementById("slider"),
    clock: document.getElementById("clock"),
    play: document.getElementById("play"),
    speed: document.getElementById("speed"),
    now: document.getElementById("now"),
    chartLegend: document.getElementById("chart-legend"),
  };

  let model = null;
  let A = null;
  const cam = { scale: 1, ox: 0, oy: 0, w: 0, h: 0, fitted: false };
  const mouse = { x: -1, y: -1, inside: false, drag: null };
  const play = { on: false, speed: 1, last: 0 };
  const stats = { frames: 0, drawMs: [], intervals: [], lastFrame: 0 };
  let drawn = { links: 0, hops: 0, hovered: -1 };
  let mapCanvas = null;
  let chartBase = null;
  let dirty = true;
  let panelStamp = 0;

  const SX = (x) => cam.ox + x * cam.scale;
  const SY = (y) => cam.oy - y * cam.scale;

  // The area [x0, y0, x1, y1] in the world frame (the square [0, side_m]^2 by default).
  const AREA = META.bounds_m || [0, 0, META.side_m, META.side_m];

  function fit() {
    const [x0, y0, x1, y1] = AREA;
    cam.scale = 0.96 * Math.min(cam.w / (x1 - x0), cam.h / (y1 - y0));
    cam.ox = (cam.w - (x1 - x0) * cam.scale) / 2 - x0 * cam.scale;
    cam.oy = (cam.h + (y1 - y0) * cam.scale) / 2 + y0 * cam.scale;
    cam.fitted = true;
  }

  function resize() {
    const dpr = window.devicePixelRatio || 1;
    const box = field.parentElement.getBoundingClientRect();
    const w = Math.max(50, box.width), h = Math.max(50, box.height);
    const changed = w !== cam.w || h !== cam.h;
    cam.w = w;
    cam.h = h;
    field.width = Math.round(w * dpr);
    field.height = Math.round(h * dpr);
    if (!cam.fitted || changed) fit();
    const cb = chartCanvas.getBoundingClientRect();
    chartCanvas.width = Math.round(Math.max(50, cb.width) * dpr);
    chartCanvas.height = Math.round(Math.max(30, cb.height) * dpr);
    chartBase = null;
    dirty = true;
  }

  function robotRadius() {
    // About an eighth of the typical spacing between robots, on screen.
    const spacingPx = (Math.sqrt((AREA[2] - AREA[0]) * (AREA[3] - AREA[1])) * cam.scale) / Math.sqrt(Math.max(1, META.n));
    return Math.max(2, Math.min(7, spacingPx / 8));
  }

  function buildMap() {
    const m = META.map;
    if (!m) return;
    const occ = A.map_occupied;
    const c = document.createElement("canvas");
    c.width = m.width;
    c.height = m.height;
    const g = c.getContext("2d");
    const img = g.createImageData(m.width, m.height);
    const rgb = [parseInt(PAL.wall.slice(1, 3), 16), parseInt(PAL.wall.slice(3, 5), 16), parseInt(PAL.wall.slice(5, 7), 16)];
    for (let row = 0; row < m.height; row++) {
      // Row 0 of the grid is at the bottom, row 0 of an image at the top.
      const dst = (m.height - 1 - row) * m.width;
      for (let col = 0; col < m.width; col++) {
        if (!occ[row * m.width + col]) continue;
        const p = 4 * (dst + col);
        img.data[p] = rgb[0];
        img.data[p + 1] = rgb[1];
        img.data[p + 2] = rgb[2];
        img.data[p + 3] = 255;
      }
    }
    g.putImageData(img, 0, 0);
    mapCanvas = c;
    document.getElementById("walls-row").hidden = false;
  }

  // Scratch buffers for bucketing robots by colour (counting sort, O(N) a frame).
  let bucketStart = null, bucketOrder = null, colourIdx = null;
  const NB = GROUPS.length + 1; // last bucket: no group

  function bucketRobots(filter, colourOf = (i) => model.colour(i)) {
    const n = model.n;
    bucketStart.fill(0);
    for (let i = 0; i < n; i++) {
      if (!filter(i)) {
        colourIdx[i] = -2;
        continue;
      }
      const c = colourOf(i);
      colourIdx[i] = c < 0 ? NB - 1 : c;
      bucketStart[colourIdx[i] + 1]++;
    }
    for (let b = 0; b < NB; b++) bucketStart[b + 1] += bucketStart[b];
    const fill = bucketStart.slice(0, NB);
    for (let i = 0; i < n; i++) if (colourIdx[i] >= 0) bucketOrder[fill[colourIdx[i]]++] = i;
  }

  function bucketColour(b, none = PAL.no_group) {
    return b === NB - 1 ? none : GROUPS[b];
  }

  // Half the size of a marker of a role, for members drawn r pixels in radius: marker
  // sizes scale as in matplotlib (the size is the area).
  function markerSize(role, r) {
    return r * Math.sqrt(PAL.roles[role].size / PAL.roles.beta.size);
  }

  // A matplotlib marker's shape, centred at (X, Y), s half its size.
  function markerPath(g, marker, X, Y, s) {
    if (marker === "^") {
      g.moveTo(X, Y - s);
      g.lineTo(X + 0.866 * s, Y + 0.5 * s);
      g.lineTo(X - 0.866 * s, Y + 0.5 * s);
      g.closePath();
    } else if (marker === "s") g.rect(X - s, Y - s, 2 * s, 2 * s);
    else if (marker === "x") {
      g.moveTo(X - s, Y - s);
      g.lineTo(X + s, Y + s);
      g.moveTo(X - s, Y + s);
      g.lineTo(X + s, Y - s);
    } else if (marker === "+") {
      g.moveTo(X - s, Y);
      g.lineTo(X + s, Y);
      g.moveTo(X, Y - s);
      g.lineTo(X, Y + s);
    } else {
      g.moveTo(X + s, Y);
      g.arc(X, Y, s, 0, 2 * Math.PI);
    }
  }

  // Fill and edge colours of robot i as drawn ("" for no edge).
  function fillOf(i) {
    const st = PAL.roles[NO_ROLES ? "none" : model.shape(i)];
    if (st.colour !== "group") return st.colour;
    const c = model.colour(i);
    return c < 0 ? PAL.no_group : GROUPS[c];
  }
  function edgeOf(i) {
    const st = PAL.roles[NO_ROLES ? "none" : model.shape(i)];
    if (st.edge === "none" || LINE_MARKERS.has(st.marker)) return "";
    if (st.edge !== "group") return st.edge;
    const c = model.edgeColour(i);
    return c < 0 ? PAL.no_group : GROUPS[c];
  }

  // The robots of one role (all, as "none", in a run without roles): shaped, filled and
  // edged as its style says, one path per colour.
  function drawRole(role, r) {
    const st = PAL.roles[role];
    const s = markerSize(role, r), x = model.x, y = model.y;
    const mine = NO_ROLES ? () => true : (i) => model.shape(i) === role;
    const line = LINE_MARKERS.has(st.marker);
    const fixed = st.colour !== "group";
    const paths = (colourOf, none, paint) => {
      bucketRobots(mine, colourOf);
      for (let b = 0; b < NB; b++) {
        if (bucketStart[b] === bucketStart[b + 1]) continue;
        ctx.beginPath();
        for (let k = bucketStart[b]; k < bucketStart[b + 1]; k++) {
          const i = bucketOrder[k];
          markerPath(ctx, st.marker, SX(x[i]), SY(y[i]), s);
        }
        paint(bucketColour(b, none));
      }
    };
    ctx.lineWidth = 1.5;
    paths(fixed ? () => -1 : (i) => model.colour(i), fixed ? st.colour : PAL.no_group, (c) => {
      if (line) {
        ctx.strokeStyle = c;
        ctx.stroke();
      } else {
        ctx.fillStyle = c;
        ctx.fill();
      }
    });
    if (st.edge === "none" || line) return;
    const byGroup = st.edge === "group";
    ctx.lineWidth = byGroup ? 2 : 1;
    paths(byGroup ? (i) => model.edgeColour(i) : () => -1, byGroup ? PAL.no_group : st.edge, (c) => {
      ctx.strokeStyle = c;
      ctx.stroke();
    });
  }

  function drawField() {
    const dpr = window.devicePixelRatio || 1;
    const n = model.n, x = model.x, y = model.y, t = model.t;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, cam.w, cam.h);
    ctx.strokeStyle = PAL.border;
    ctx.lineWidth = 1;
    ctx.strokeRect(SX(AREA[0]), SY(AREA[3]), (AREA[2] - AREA[0]) * cam.scale, (AREA[3] - AREA[1]) * cam.scale);

    if (mapCanvas && ui.walls.checked) {
      const m = META.map;
      ctx.imageSmoothingEnabled = false;
      ctx.drawImage(mapCanvas, SX(m.origin_m[0]), SY(m.origin_m[1] + m.height * m.resolution_m), m.width * m.resolution_m * cam.scale, m.height * m.resolution_m * cam.scale);
    }

    const disks = ui.disks.value;
    if (disks !== "off") {
      const rad = META.coverage_radius_m * cam.scale;
      bucketRobots(disks === "leaders" ? (i) => model.role[i] === ALPHA : () => true);
      ctx.globalAlpha = PAL.disk_alpha;
      for (let b = 0; b < NB; b++) {
        if (bucketStart[b] === bucketStart[b + 1]) continue;
        ctx.fillStyle = bucketColour(b);
        ctx.beginPath();
        for (let k = bucketStart[b]; k < bucketStart[b + 1]; k++) {
          const i = bucketOrder[k];
          ctx.moveTo(SX(x[i]) + rad, SY(y[i]));
          ctx.arc(SX(x[i]), SY(y[i]), rad, 0, 2 * Math.PI);
        }
        ctx.fill();
      }
      ctx.globalAlpha = 1;
    }

    drawn.links = 0;
    if (ui.links.checked && model.nActive > 0) {
      inArea(() => {
        ctx.strokeStyle = PAL.link;
        ctx.lineWidth = 1;
        ctx.beginPath();
        for (let k = 0; k < model.nActive; k++) segment(A.link_a[model.active[k]], A.link_b[model.active[k]], 1);
        ctx.stroke();
      });
      drawn.links = model.nActive;
    }

    drawn.hops = 0;
    if (ui.hops.checked && META.has.hops) inArea(() => drawHops(t));

    const r = robotRadius();
    for (const role of NO_ROLES ? ["none"] : ["beta", "gamma", "gateway", "alpha"]) drawRole(role, r);

    drawn.hovered = mouse.inside && !mouse.drag ? nearest(mouse.x, mouse.y, Math.max(8, 2 * r)) : -1;
    if (drawn.hovered >= 0) {
      const i = drawn.hovered;
      ctx.strokeStyle = PAL.outline;
      ctx.lineWidth = 2;
      inArea(() => {
        ctx.beginPath();
        for (const j of model.neighbours(i)) segment(i, j, 1);
        ctx.stroke();
      });
      ctx.beginPath();
      ctx.arc(SX(x[i]), SY(y[i]), 2.5 * r + 3, 0, 2 * Math.PI);
      ctx.stroke();
    }
  }

  // draw() with the canvas clipped to the area on a torus: a segment across the seam runs
  // to the other robot's image past the border, and shows only up to the border, from
  // both sides (as the figures draw it). On a plane every segment lies inside the area.
  function inArea(draw) {
    if (!META.torus) {
      draw();
      return;
    }
    ctx.save();
    ctx.beginPath();
    ctx.rect(SX(AREA[0]), SY(AREA[3]), (AREA[2] - AREA[0]) * cam.scale, (AREA[3] - AREA[1]) * cam.scale);
    ctx.clip();
    draw();
    ctx.restore();
  }

  // The segment from robot a toward b (the shortest image on a torus), a fraction f of the way.
  function segment(a, b, f) {
    const x = model.x, y = model.y, side = META.side_m;
    let dx = x[b] - x[a], dy = y[b] - y[a];
    if (META.torus) {
      dx = nearestImage(dx, side);
      dy = nearestImage(dy, side);
      if (f >= 1 && (dx !== x[b] - x[a] || dy !== y[b] - y[a])) {
        // Across the border: draw both halves, each from its own end.
        ctx.moveTo(SX(x[b]), SY(y[b]));
        ctx.lineTo(SX(x[b] - dx), SY(y[b] - dy));
      }
    }
    ctx.moveTo(SX(x[a]), SY(y[a]));
    ctx.lineTo(SX(x[a] + f * dx), SY(y[a] + f * dy));
  }

  const TRAIL_LEVELS = 6;
  function drawHops(t) {
    const trail = parseFloat(ui.trail.value), w = trail / TRAIL_LEVELS;
    const ts = A.hop_t_sent, tr = A.hop_t_received;
    ctx.strokeStyle = PAL.message;
    ctx.lineWidth = 1;
    // Sorted by sending time, so each age band (fading with age) is one contiguous run.
    for (let level = 0; level < TRAIL_LEVELS; level++) {
      const hi = lastAtOrBefore(ts, t - level * w) + 1;
      const lo = lastAtOrBefore(ts, t - (level + 1) * w, 0, hi) + 1;
      if (hi <= lo) continue;
      ctx.globalAlpha = 1 - level / TRAIL_LEVELS;
      ctx.beginPath();
      for (let k = lo; k < hi; k++) {
        // A transmission in flight is drawn as far as it has come.
        const f = tr[k] > ts[k] ? Math.min(1, (t - ts[k]) / (tr[k] - ts[k])) : 1;
        segment(A.hop_sender[k], A.hop_receiver[k], f);
      }
      ctx.stroke();
      drawn.hops += hi - lo;
    }
    ctx.globalAlpha = 1;
    ctx.lineWidth = 2;
    // The messages' sources and destinations: rings (filled when it arrived).
    const mt = A.msg_t;
    const mhi = lastAtOrBefore(mt, t) + 1;
    const mlo = lastAtOrBefore(mt, t - trail, 0, mhi) + 1;
    const r = robotRadius() * 2.6;
    for (let m = mlo; m < mhi; m++) {
      const s = A.msg_src[m], d = A.msg_dst[m];
      ctx.beginPath();
      ctx.arc(SX(model.x[s]), SY(model.y[s]), r, 0, 2 * Math.PI);
      ctx.stroke();
      ctx.beginPath();
      ctx.setLineDash([3, 2]);
      ctx.arc(SX(model.x[d]), SY(model.y[d]), r, 0, 2 * Math.PI);
      ctx.stroke();
      ctx.setLineDash([]);
      if (A.msg_delivered[m] && A.msg_t_delivered[m] <= t) {
        ctx.globalAlpha = 0.35;
        ctx.fillStyle = PAL.message;
        ctx.fill();
        ctx.globalAlpha = 1;
      }
    }
  }

  function nearest(px, py, maxPx) {
    let best = -1, bestD = maxPx * maxPx;
    const x = model.x, y = model.y;
    for (let i = 0; i < model.n; i++) {
      const dx = SX(x[i]) - px, dy = SY(y[i]) - py, d = dx * dx + dy * dy;
      if (d <= bestD) {
        bestD = d;
        best = i;
      }
    }
    return best;
  }

  const fmt = (v, d = 2) => (Number.isInteger(v) ? String(v) : v.toFixed(d));

  // "3 [1, 4, 9]": how many, and which (the first 24).
  function idList(ids) {
    if (!ids.length) return "0";
    const shown = ids.length > 24 ? ids.slice(0, 24).join(", ") + ", …" : ids.join(", ");
    return `${ids.length} [${shown}]`;
  }

  // Robot i's neighbours by id at the last beliefs sample at or before the cursor: those
  // it believed live, those whose transmissions reached it, and the differences (null
  // without the neighbour_beliefs table or before the first sample).
  function neighbourBeliefs(i) {
    if (!META.has.neighbour_beliefs) return null;
    const k = lastAtOrBefore(A.bel_t, model.t);
    if (k < 0) return null;
    const out = { t: A.bel_t[k], believed: [], inRange: [], stale: [], missing: [] };
    for (let r = A.nb_first[i]; r < A.nb_first[i + 1]; r++) {
      if (A.nb_k0[r] > k || A.nb_k1[r] < k) continue;
      const j = A.nb_id[r], f = A.nb_flags[r];
      if (f & 1) out.believed.push(j);
      if (f & 2) out.inRange.push(j);
      if (f === 1) out.stale.push(j);
      if (f === 2) out.missing.push(j);
    }
    return out;
  }

  function updateTip() {
    const i = drawn.hovered;
    if (i < 0) {
      tip.hidden = true;
      return;
    }
    const shape = model.shape(i);
    const lines = [NO_ROLES ? `robot ${i}` : `robot ${i}: ${PAL.roles[shape].label}`];
    const leader = model.role[i] === ALPHA ? i : model.leader[i];
    if (!NO_ROLES) lines.push(`leader ${leader >= 0 ? leader : "none"}`);
    const groups = model.groupsOf(i);
    if (groups.length) lines.push(`groups ${groups.join(", ")}`);
    lines.push(`position (${model.x[i].toFixed(1)}, ${model.y[i].toFixed(1)}) m`);
    const nb = model.neighbours(i);
    lines.push(`true neighbours now: ${idList(nb)}`);
    if (META.has.beliefs) {
      const k = lastAtOrBefore(A.bel_t, model.t);
      if (k >= 0) {
        const at = k * model.n + i;
        const when = `at t = ${fmt(A.bel_t[k])} s`;
        const ids = neighbourBeliefs(i);
        if (ids) {
          lines.push(`believed ${when}: ${idList(ids.believed)}`);
          lines.push(`in range then: ${idList(ids.inRange)}`);
          lines.push(`  believed, not in range (stale): ${idList(ids.stale)}`);
          lines.push(`  in range, not believed (missing): ${idList(ids.missing)}`);
        } else {
          lines.push(`believed ${when}: ${A.bel_believed[at]} (true then ${A.bel_true[at]}, stale ${A.bel_stale[at]}, missing ${A.bel_missing[at]})`);
        }
        if (model.role[i] === BETA) lines.push(`leader in range then: ${A.bel_leader_in_range[at] ? "yes" : "no"}`);
      }
    }
    tip.textContent = lines.join("\n");
    tip.hidden = false;
    const box = field.parentElement.getBoundingClientRect();
    const w = tip.offsetWidth, h = tip.offsetHeight;
    tip.style.left = `${Math.min(mouse.x + 14, box.width - w - 4)}px`;
    tip.style.top = `${Math.min(mouse.y + 14, box.height - h - 4)}px`;
  }

  // ---------------------------------------------------------------- strip chart
  function chartScale() {
    let countMax = 1;
    for (const s of META.series) {
      if (s.axis !== "count") continue;
      const v = A[`s_${s.name}_v`];
      for (let k = 0; k < v.length; k++) if (v[k] > countMax) countMax = v[k];
    }
    return Math.ceil(countMax * 1.1);
  }

  function buildChart() {
    const dpr = window.devicePixelRatio || 1;
    const c = document.createElement("canvas");
    c.width = chartCanvas.width;
    c.height = chartCanvas.height;
    const g = c.getContext("2d");
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    const w = c.width / dpr, h = c.height / dpr, pad = 14;
    const countMax = chartScale();
    const X = (t) => (t / META.duration_s) * w;
    g.fillStyle = PAL.chart.background;
    g.fillRect(0, 0, w, h);
    g.strokeStyle = PAL.chart.grid;
    g.lineWidth = 1;
    g.beginPath();
    for (const f of [0, 0.5, 1]) {
      g.moveTo(0, pad + (1 - f) * (h - 2 * pad));
      g.lineTo(w, pad + (1 - f) * (h - 2 * pad));
    }
    g.stroke();
    g.fillStyle = PAL.chart.text;
    g.font = "10px sans-serif";
    g.fillText(`counts 0–${countMax}`, 4, 10);
    g.textAlign = "right";
    g.fillText("fractions 0–1", w - 4, 10);
    META.series.forEach((s) => {
      const t = A[`s_${s.name}_t`], v = A[`s_${s.name}_v`];
      const top = s.axis === "count" ? countMax : 1;
      const Y = (val) => pad + (1 - val / top) * (h - 2 * pad);
      g.strokeStyle = seriesColour(s);
      g.lineWidth = 1.5;
      g.beginPath();
      let started = false;
      for (let k = 0; k < t.length; k++) {
        if (!Number.isFinite(v[k])) {
          started = false;
          continue;
        }
        if (!started) {
          g.moveTo(X(t[k]), Y(v[k]));
          started = true;
        } else if (s.kind === "step") {
          g.lineTo(X(t[k]), Y(v[k - 1]));
          g.lineTo(X(t[k]), Y(v[k]));
        } else g.lineTo(X(t[k]), Y(v[k]));
      }
      if (started && s.kind === "step" && t.length) g.lineTo(w, Y(v[t.length - 1]));
      g.stroke();
    });
    chartBase = c;
  }

  function drawChart() {
    if (!chartBase) buildChart();
    const dpr = window.devicePixelRatio || 1;
    chartCtx.setTransform(1, 0, 0, 1, 0, 0);
    chartCtx.drawImage(chartBase, 0, 0);
    chartCtx.setTransform(dpr, 0, 0, dpr, 0, 0);
    const w = chartCanvas.width / dpr, h = chartCanvas.height / dpr;
    const X = (model.t / META.duration_s) * w;
    chartCtx.strokeStyle = PAL.chart.cursor;
    chartCtx.lineWidth = 1;
    chartCtx.beginPath();
    chartCtx.moveTo(X, 0);
    chartCtx.lineTo(X, h);
    chartCtx.stroke();
  }

  function seriesColour(s) {
    return PAL.series[s.name] || PAL.other_series;
  }

  function seriesAt(s, t) {
    const ts = A[`s_${s.name}_t`], v = A[`s_${s.name}_v`];
    const k = lastAtOrBefore(ts, t);
    return k < 0 ? NaN : v[k];
  }

  function updatePanels() {
    const t = model.t, n = model.n;
    let leaders = 0, members = 0, gateways = 0, undecided = 0;
    for (let i = 0; i < n; i++) {
      const r = model.role[i];
      if (r === ALPHA) leaders++;
      else if (r === BETA) {
        members++;
        if (model.gateway[i]) gateways++;
      } else undecided++;
    }
    const comps = model.components();
    view.components = comps;
    const lines = [`t = ${t.toFixed(2)} s`];
    if (!NO_ROLES) lines.push(`leaders ${leaders}, members ${members} (gateways ${gateways}), undecided ${undecided}`);
    lines.push(`links up ${model.nActive}, components ${comps}`);
    if (META.has.messages) {
      const sent = lastAtOrBefore(A.msg_t, t) + 1;
      let arrived = 0;
      for (let m = 0; m < sent; m++) if (A.msg_delivered[m] && A.msg_t_delivered[m] <= t) arrived++;
      lines.push(`${META.message_noun ?? "message"}s sent ${sent}, arrived ${arrived}`);
    }
    ui.now.textContent = lines.join("\n");
    ui.chartLegend.replaceChildren(
      ...META.series.map((s) => {
        const span = document.createElement("span");
        const key = document.createElement("span");
        key.className = "key";
        key.style.background = seriesColour(s);
        const v = seriesAt(s, t);
        span.append(key, `${s.label}: ${Number.isFinite(v) ? fmt(v, s.axis === "count" ? 0 : 3) : "–"}`);
        return span;
      }),
    );
  }

  // ---------------------------------------------------------------- time and the loop
  function setTime(t) {
    t = Math.min(META.duration_s, Math.max(0, Number(t)));
    model.seek(t);
    ui.slider.value = String(t);
    ui.clock.textContent = `t = ${t.toFixed(2)} / ${fmt(META.duration_s)} s`;
    dirty = true;
  }

  function render(force) {
    if (!dirty && !force) return;
    const start = performance.now();
    drawField();
    drawChart();
    const now = performance.now();
    if (force || !play.on || now - panelStamp > 100) {
      updatePanels();
      panelStamp = now;
    }
    updateTip();
    stats.drawMs.push(now - start);
    if (stats.drawMs.length > 600) stats.drawMs.shift();
    stats.frames++;
    dirty = false;
  }

  function setPlaying(on) {
    play.on = on;
    play.last = performance.now();
    ui.play.textContent = on ? "❚❚ pause" : "▶ play";
  }

  function frame(now) {
    if (stats.lastFrame) {
      stats.intervals.push(now - stats.lastFrame);
      if (stats.intervals.length > 600) stats.intervals.shift();
    }
    stats.lastFrame = now;
    if (play.on) {
      const dt = Math.max(0, now - play.last) / 1000;
      play.last = now;
      const t = model.t + dt * play.speed;
      setTime(t);
      if (t >= META.duration_s) setPlaying(false);
    }
    render(false);
    requestAnimationFrame(frame);
  }

  // ---------------------------------------------------------------- controls
  function options(select, values, chosen, label) {
    for (const v of values) {
      const o = document.createElement("option");
      o.value = String(v);
      o.textContent = label(v);
      if (v === chosen) o.selected = true;
      select.append(o);
    }
  }

  function legend() {
    const box = document.getElementById("legend");
    const icon = (draw) => {
      const c = document.createElement("canvas");
      c.width = c.height = 16;
      draw(c.getContext("2d"));
      return c;
    };
    const row = (canvas, text) => {
      const div = document.createElement("div");
      div.append(canvas, text);
      return div;
    };
    const line = (colour) => (g) => {
      g.strokeStyle = colour;
      g.lineWidth = 2;
      g.beginPath();
      g.moveTo(1, 8);
      g.lineTo(15, 8);
      g.stroke();
    };
    const rows = [];
    for (const role of NO_ROLES ? ["none"] : ["alpha", "beta", "gateway", "gamma"]) {
      const st = PAL.roles[role];
      const s = Math.min(6.5, markerSize(role, 4));
      // The group colours of the legend: the first two of the palette.
      const fill = st.colour === "group" ? GROUPS[0] : st.colour;
      const edge = st.edge === "group" ? GROUPS[1] : st.edge;
      const drawIcon = (g) => {
        g.beginPath();
        markerPath(g, st.marker, 8, 8, s);
        if (LINE_MARKERS.has(st.marker)) {
          g.strokeStyle = fill;
          g.lineWidth = 1.5;
          g.stroke();
          return;
        }
        g.fillStyle = fill;
        g.fill();
        if (edge !== "none") {
          g.strokeStyle = edge;
          g.lineWidth = st.edge === "group" ? 2 : 1;
          g.stroke();
        }
      };
      rows.push(row(icon(drawIcon), NO_ROLES ? `${st.label}: protocol "${META.protocol}"` : st.label));
    }
    rows.push(row(icon(line(PAL.link)), "link"));
    if (META.message_noun === "packet") {
      document.getElementById("hops-label").textContent = "routed packets";
      document.getElementById("trail-label").textContent = "packet trail";
    }
    if (META.has.hops) {
      const what = META.message_noun === "packet" ? "routed packet" : "relayed message";
      rows.push(row(icon(line(PAL.message)), `${what} (source ring, destination dashed)`));
    }
    if (!NO_ROLES) {
      const note = document.createElement("div");
      note.textContent = "colour: the group (its leader), the same for the whole run";
      rows.push(note);
    }
    box.replaceChildren(...rows);
  }

  function workflow() {
    const form = document.getElementById("form");
    const out = document.getElementById("command");
    const sc = META.scenario;
    for (const el of form.elements) {
      const v = sc[el.name];
      if (Array.isArray(v)) {
        // One value a robot (ranges): left empty, so that the command keeps the run's own
        // list unless a value for all is typed in.
        el.value = "";
        el.placeholder = `per robot, ${Math.min(...v)}-${Math.max(...v)}`;
      } else el.value = v;
    }
    const keys = {
      n_robots: "world.n_robots",
      speed_min_mps: "mobility.speed_min_mps",
      speed_max_mps: "mobility.speed_max_mps",
      duration_s: "duration_s",
      range_m: "channel.range_m",
    };
    const update = () => {
      const parts = [`netsim run ${META.title}/config.toml`];
      for (const [name, key] of Object.entries(keys)) {
        const v = form.elements[name].value;
        if (v !== "") parts.push(`--set ${key}=${v}`);
      }
      if (form.elements.seed.value !== "") parts.push(`--seed ${form.elements.seed.value}`);
      parts.push(`--out ${META.title}-next --view`);
      out.textContent = parts.join(" \\\n  ");
    };
    form.addEventListener("input", update);
    update();
  }

  function wire() {
    const d = META.duration_s;
    ui.slider.max = String(d);
    const speeds = [0.01, 0.1, 0.25, 0.5, 1, 2, 5, 10, 20, 50, 100];
    play.speed = speeds.filter((s) => s <= Math.max(1, d / 30)).pop();
    options(ui.speed, speeds, play.speed, (v) => `${v}×`);
    options(ui.trail, [0.1, 0.5, 1, 2, 5, 10], 2, (v) => `${v} s`);
    ui.speed.addEventListener("change", () => (play.speed = parseFloat(ui.speed.value)));
    ui.slider.addEventListener("input", () => setTime(parseFloat(ui.slider.value)));
    ui.play.addEventListener("click", () => togglePlay());
    const step = (k) => setTime(model.t + k * META.step_s);
    document.getElementById("back").addEventListener("click", (e) => step(e.shiftKey ? -10 : -1));
    document.getElementById("fwd").addEventListener("click", (e) => step(e.shiftKey ? 10 : 1));
    for (const el of [ui.links, ui.hops, ui.trail, ui.disks, ui.walls]) el.addEventListener("change", () => (dirty = true));
    document.addEventListener("keydown", (e) => {
      if (e.target instanceof HTMLInputElement && e.target.type !== "range") return;
      if (e.key === " ") {
        e.preventDefault();
        togglePlay();
      } else if (e.key === "ArrowRight") step(e.shiftKey ? 10 : 1);
      else if (e.key === "ArrowLeft") step(e.shiftKey ? -10 : -1);
    });
    field.addEventListener("mousemove", (e) => {
      const box = field.getBoundingClientRect();
      const mx = e.clientX - box.left, my = e.clientY - box.top;
      if (mouse.drag) {
        cam.ox += mx - mouse.drag.x;
        cam.oy += my - mouse.drag.y;
        mouse.drag = { x: mx, y: my };
      }
      mouse.x = mx;
      mouse.y = my;
      mouse.inside = true;
      dirty = true;
    });
    field.addEventListener("mouseleave", () => {
      mouse.inside = false;
      mouse.drag = null;
      dirty = true;
    });
    field.addEventListener("mousedown", (e) => {
      const box = field.getBoundingClientRect();
      mouse.drag = { x: e.clientX - box.left, y: e.clientY - box.top };
    });
    window.addEventListener("mouseup", () => {
      mouse.drag = null;
      dirty = true;
    });
    field.addEventListener("dblclick", () => {
      fit();
      dirty = true;
    });
    field.addEventListener(
      "wheel",
      (e) => {
        e.preventDefault();
        const box = field.getBoundingClientRect();
        const mx = e.clientX - box.left, my = e.clientY - box.top;
        const f = Math.exp(-e.deltaY * 0.0015);
        cam.ox = mx - (mx - cam.ox) * f;
        cam.oy = my - (my - cam.oy) * f;
        cam.scale *= f;
        dirty = true;
      },
      { passive: false },
    );
    chartCanvas.addEventListener("click", (e) => {
      const box = chartCanvas.getBoundingClientRect();
      setTime(((e.clientX - box.left) / box.width) * META.duration_s);
    });
    // The field's box changes with the window and with the panels' contents.
    new ResizeObserver(() => resize()).observe(field.parentElement);
    legend();
    workflow();
  }

  function togglePlay() {
    if (!play.on && model.t >= META.duration_s) setTime(0);
    setPlaying(!play.on);
  }

  function header() {
    document.getElementById("title").textContent = `netsim replay: ${META.title}`;
    const s = META.summary;
    const facts = [
      `${META.n} robot${META.n === 1 ? "" : "s"}`,
      META.torus || (AREA[0] === 0 && AREA[1] === 0 && AREA[2] === AREA[3])
        ? `${fmt(META.torus ? META.side_m : AREA[2])} m ${META.torus ? "torus" : "square"}`
        : `area x ${fmt(AREA[0])} to ${fmt(AREA[2])} m, y ${fmt(AREA[1])} to ${fmt(AREA[3])} m`,
      `${fmt(META.duration_s)} s`,
      `${META.mobility}`,
      `protocol ${META.protocol}`,
      `seed ${META.seed}`,
    ];
    if (Number.isFinite(s.ack_delivery_ratio)) facts.push(`Ack delivery ratio ${s.ack_delivery_ratio.toFixed(3)} (whole run)`);
    if (META.motion !== "legs") facts.push("positions interpolated between samples (no legs.parquet)");
    document.getElementById("facts").textContent = facts.join(" · ");
  }

  // ---------------------------------------------------------------- the test interface
  function expose() {
    // defineProperties, not Object.assign: the getters must stay getters.
    const api = {
      n: META.n,
      duration: META.duration_s,
      get t() {
        return model.t;
      },
      get playing() {
        return play.on;
      },
      get speed() {
        return play.speed;
      },
      get linksDrawn() {
        return drawn.links;
      },
      get hopsDrawn() {
        return drawn.hops;
      },
      get frames() {
        return stats.frames;
      },
      seek(t) {
        setTime(t);
        render(true);
        return model.t;
      },
      play() {
        if (!play.on) togglePlay();
      },
      pause() {
        setPlaying(false);
      },
      setSpeed(s) {
        play.speed = Number(s);
      },
      positions: () => Array.from(model.x, (x, i) => [x, model.y[i]]),
      roles: () => Array.from(model.role, (r) => ROLE_NAMES[r]),
      shapes: () => Array.from(model.role, (_, i) => (NO_ROLES ? "none" : model.shape(i))),
      leaders: () => Array.from(model.leader),
      links: () => Array.from(model.active.subarray(0, model.nActive), (l) => [A.link_a[l], A.link_b[l]]),
      screenOf: (i) => [SX(model.x[i]), SY(model.y[i])],
      toScreen: (x, y) => [SX(x), SY(y)],
      tooltip: () => (tip.hidden ? "" : tip.textContent),
      get hovered() {
        return drawn.hovered;
      },
      neighbourBeliefs: (i) => neighbourBeliefs(i),
      colours: () => Array.from(model.role, (_, i) => fillOf(i)),
      edges: () => Array.from(model.role, (_, i) => edgeOf(i)),
      palette: () => PAL,
      series: () => Object.fromEntries(META.series.map((s) => [s.name, seriesAt(s, model.t)])),
      stats: () => ({ drawMs: stats.drawMs.slice(), intervals: stats.intervals.slice() }),
    };
    Object.defineProperties(view, Object.getOwnPropertyDescriptors(api));
  }

  async function main() {
    try {
      header();
      A = await decode();
      model = new Model(A);
      bucketStart = new Int32Array(NB + 1);
      bucketOrder = new Int32Array(model.n);
      colourIdx = new Int32Array(model.n);
      buildMap();
      wire();
      resize();
      expose();
      setTime(0);
      render(true);
      document.getElementById("loading").remove();
      view.ready = true;
      requestAnimationFrame(frame);
    } catch (err) {
      view.error = String(err && err.stack ? err.stack : err);
      document.getElementById("loading").textContent = `cannot show this run: ${err}`;
      console.error(err);
    }
  }

  main();
})();
