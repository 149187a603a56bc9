// slam2world report page: a small WebGL 2 viewer (points, lines, instanced
// cubes, an orbit camera with z up) and canvas plots, over the JSON block
// #s2w-data. Nothing is loaded from the network.
(function () {
  "use strict";
  var statusEl = document.getElementById("s2w-status");
  var problems = [];

  function fail(where, e) {
    var text = where + ": " + (e && e.message ? e.message : String(e));
    problems.push(text);
    console.error("slam2world report: " + text);
  }

  // ---- data ----------------------------------------------------------------
  function bytes(s) {
    var bin = atob(s);
    var out = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  }
  function floats(s) {
    var b = bytes(s);
    return new Float32Array(b.buffer, 0, b.length >> 2);
  }

  // ---- colours -------------------------------------------------------------
  var VIRIDIS = [[68, 1, 84], [72, 40, 120], [62, 74, 137], [49, 104, 142], [38, 130, 142],
    [31, 158, 137], [53, 183, 121], [109, 205, 89], [180, 222, 44], [253, 231, 37]];
  var PLASMA = [[13, 8, 135], [84, 2, 163], [139, 10, 165], [185, 50, 137], [219, 92, 104],
    [244, 136, 73], [254, 188, 43], [240, 249, 33]];
  function cmap(lut, t) {
    if (!(t >= 0)) t = 0;
    if (t > 1) t = 1;
    var x = t * (lut.length - 1);
    var i = Math.min(Math.floor(x), lut.length - 2);
    var f = x - i;
    return [0, 1, 2].map(function (k) { return (lut[i][k] * (1 - f) + lut[i + 1][k] * f) / 255; });
  }
  function css(c) {
    return "rgb(" + c.map(function (v) { return Math.round(v * 255); }).join(",") + ")";
  }
  function colorbar(el, lut, lo, hi, label) {
    if (!el) return;
    var stops = [];
    for (var i = 0; i <= 10; i++) stops.push(css(cmap(lut, i / 10)) + " " + i * 10 + "%");
    el.innerHTML = "<div>" + label + "</div><div class=\"bar\" style=\"background:linear-gradient(to right," +
      stops.join(",") + ")\"></div><div class=\"ends\"><span>" + fmt(lo) + "</span><span>" + fmt(hi) + "</span></div>";
  }
  function fmt(v) {
    if (!isFinite(v)) return "—";
    var a = Math.abs(v);
    if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(2);
    return String(Number(v.toPrecision(4)));
  }
  // Smallest and largest finite value (a loop: spreading a long array into
  // Math.min would overflow the call stack).
  function extent(values) {
    var lo = Infinity, hi = -Infinity;
    for (var i = 0; i < values.length; i++) {
      var v = values[i];
      if (isFinite(v)) { if (v < lo) lo = v; if (v > hi) hi = v; }
    }
    return [lo, hi];
  }
  function quantile(values, q) {
    var v = Array.prototype.slice.call(values).filter(isFinite).sort(function (a, b) { return a - b; });
    if (!v.length) return NaN;
    return v[Math.min(v.length - 1, Math.max(0, Math.floor(q * (v.length - 1))))];
  }

  // ---- matrices (column-major) --------------------------------------------
  function perspective(fovy, aspect, near, far) {
    var f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
    return [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0];
  }
  function lookAt(e, c, up) {
    var z = norm(sub(e, c)), x = norm(cross(up, z)), y = cross(z, x);
    return [x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0,
      -dot(x, e), -dot(y, e), -dot(z, e), 1];
  }
  function mul(a, b) {
    var o = new Array(16);
    for (var c = 0; c < 4; c++) {
      for (var r = 0; r < 4; r++) {
        var s = 0;
        for (var k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
        o[c * 4 + r] = s;
      }
    }
    return o;
  }
  function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
  function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
  function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
  function norm(a) { var n = Math.sqrt(dot(a, a)) || 1; return [a[0] / n, a[1] / n, a[2] / n]; }

  // ---- the 3-D view ----------------------------------------------------------
  var VS_POINT = "#version 300 es\nuniform mat4 uMVP; uniform float uSize;\n" +
    "in vec3 aPos; in vec3 aCol; out vec3 vCol;\n" +
    "void main() { gl_Position = uMVP * vec4(aPos, 1.0); gl_PointSize = uSize; vCol = aCol; }\n";
  var FS_POINT = "#version 300 es\nprecision mediump float; uniform float uRound;\n" +
    "in vec3 vCol; out vec4 oCol;\n" +
    "void main() { if (uRound > 0.5) { vec2 d = gl_PointCoord - vec2(0.5); if (dot(d, d) > 0.25) discard; }\n" +
    "  oCol = vec4(vCol, 1.0); }\n";
  var VS_CUBE = "#version 300 es\nuniform mat4 uMVP;\n" +
    "in vec3 aCorner; in vec3 aNormal; in vec3 aCenter; in float aEdge; in vec3 aCol; out vec3 vCol;\n" +
    "void main() { gl_Position = uMVP * vec4(aCenter + aCorner * aEdge, 1.0);\n" +
    "  float l = 0.45 + 0.55 * max(dot(aNormal, normalize(vec3(0.35, 0.25, 0.9))), 0.0);\n" +
    "  vCol = aCol * l; }\n";
  var FS_CUBE = "#version 300 es\nprecision mediump float; in vec3 vCol; out vec4 oCol;\n" +
    "void main() { oCol = vec4(vCol, 1.0); }\n";

  function program(gl, vs, fs) {
    function shader(type, src) {
      var s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(s));
      return s;
    }
    var p = gl.createProgram();
    gl.attachShader(p, shader(gl.VERTEX_SHADER, vs));
    gl.attachShader(p, shader(gl.FRAGMENT_SHADER, fs));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error("program: " + gl.getProgramInfoLog(p));
    return p;
  }

  // A unit cube (edge 1, centred) as 36 vertices with face normals.
  function unitCube() {
    var faces = [[0, 1], [0, -1], [1, 1], [1, -1], [2, 1], [2, -1]];
    var pos = [], nrm = [];
    faces.forEach(function (f) {
      var a = f[0], s = f[1], u = (a + 1) % 3, v = (a + 2) % 3;
      var quad = [[-1, -1], [1, -1], [1, 1], [-1, -1], [1, 1], [-1, 1]];
      if (s < 0) quad = [[-1, -1], [1, 1], [1, -1], [-1, -1], [-1, 1], [1, 1]];
      quad.forEach(function (q) {
        var p = [0, 0, 0], n = [0, 0, 0];
        p[a] = 0.5 * s; p[u] = 0.5 * q[0]; p[v] = 0.5 * q[1]; n[a] = s;
        pos.push(p[0], p[1], p[2]); nrm.push(n[0], n[1], n[2]);
      });
    });
    return { pos: new Float32Array(pos), nrm: new Float32Array(nrm) };
  }

  function View3D(canvas) {
    var gl = canvas.getContext("webgl2", { antialias: true, preserveDrawingBuffer: true });
    if (!gl) throw new Error("this browser gives no WebGL 2 context; the 3-D view cannot be drawn");
    this.gl = gl;
    this.canvas = canvas;
    this.layers = [];
    this.pointSize = 2;
    this.pPoint = program(gl, VS_POINT, FS_POINT);
    this.pCube = program(gl, VS_CUBE, FS_CUBE);
    this.cube = unitCube();
    this.home = { target: [0, 0, 0], dist: 10, yaw: -2.2, pitch: 0.6 };
    this.cam = Object.assign({}, this.home);
    this.bindEvents();
  }
  View3D.prototype.buffer = function (data) {
    var gl = this.gl, b = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, b);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    return b;
  };
  View3D.prototype.attrib = function (prog, name, buf, size, divisor) {
    var gl = this.gl, loc = gl.getAttribLocation(prog, name);
    if (loc < 0) return;
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, size, gl.FLOAT, false, 0, 0);
    gl.vertexAttribDivisor(loc, divisor || 0);
  };
  // kind: "points" | "line" | "cubes"; xyz, rgb Float32Array (n×3), edge (cubes, n).
  View3D.prototype.add = function (kind, xyz, rgb, edge, extra) {
    var gl = this.gl, vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    var layer = { kind: kind, vao: vao, visible: true, size: 0, n: 0 };
    if (kind === "cubes") {
      this.attrib(this.pCube, "aCorner", this.buffer(this.cube.pos), 3, 0);
      this.attrib(this.pCube, "aNormal", this.buffer(this.cube.nrm), 3, 0);
      this.attrib(this.pCube, "aCenter", this.buffer(xyz), 3, 1);
      this.attrib(this.pCube, "aEdge", this.buffer(edge), 1, 1);
      this.attrib(this.pCube, "aCol", this.buffer(rgb), 3, 1);
    } else {
      this.attrib(this.pPoint, "aPos", this.buffer(xyz), 3, 0);
      this.attrib(this.pPoint, "aCol", this.buffer(rgb), 3, 0);
    }
    gl.bindVertexArray(null);
    layer.n = kind === "cubes" ? edge.length : xyz.length / 3;
    if (extra) Object.assign(layer, extra);
    this.layers.push(layer);
    return layer;
  };
  View3D.prototype.frame = function (lo, hi) {
    var c = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])];
    var r = 0.5 * Math.sqrt(dot(sub(hi, lo), sub(hi, lo))) || 1;
    this.home = { target: c, dist: 2.4 * r, yaw: -2.2, pitch: 0.6 };
    this.cam = Object.assign({}, this.home);
  };
  View3D.prototype.resize = function () {
    var dpr = window.devicePixelRatio || 1;
    var w = Math.max(1, Math.round(this.canvas.clientWidth * dpr));
    var h = Math.max(1, Math.round(this.canvas.clientHeight * dpr));
    if (this.canvas.width !== w || this.canvas.height !== h) {
      this.canvas.width = w;
      this.canvas.height = h;
    }
  };
  View3D.prototype.draw = function () {
    var gl = this.gl, cam = this.cam;
    this.resize();
    gl.viewport(0, 0, this.canvas.width, this.canvas.height);
    gl.clearColor(0.063, 0.086, 0.118, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    var cp = Math.cos(cam.pitch);
    var eye = [cam.target[0] + cam.dist * cp * Math.cos(cam.yaw), cam.target[1] + cam.dist * cp * Math.sin(cam.yaw),
      cam.target[2] + cam.dist * Math.sin(cam.pitch)];
    var aspect = this.canvas.width / this.canvas.height;
    var mvp = mul(perspective(0.8, aspect, cam.dist / 500, cam.dist * 50), lookAt(eye, cam.target, [0, 0, 1]));
    var m = new Float32Array(mvp);
    var self = this;
    this.layers.forEach(function (l) {
      if (!l.visible || !l.n) return;
      gl.bindVertexArray(l.vao);
      if (l.kind === "cubes") {
        gl.useProgram(self.pCube);
        gl.uniformMatrix4fv(gl.getUniformLocation(self.pCube, "uMVP"), false, m);
        gl.drawArraysInstanced(gl.TRIANGLES, 0, 36, l.n);
      } else {
        gl.useProgram(self.pPoint);
        gl.uniformMatrix4fv(gl.getUniformLocation(self.pPoint, "uMVP"), false, m);
        var size = (l.size || self.pointSize) * (window.devicePixelRatio || 1);
        gl.uniform1f(gl.getUniformLocation(self.pPoint, "uSize"), size);
        gl.uniform1f(gl.getUniformLocation(self.pPoint, "uRound"), size > 2.5 ? 1 : 0);
        gl.drawArrays(l.kind === "line" ? gl.LINE_STRIP : gl.POINTS, 0, l.n);
      }
    });
    gl.bindVertexArray(null);
  };
  View3D.prototype.redraw = function () {
    var self = this;
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(function () { self.pending = false; self.draw(); });
  };
  View3D.prototype.bindEvents = function () {
    var self = this, c = this.canvas, drag = null;
    c.addEventListener("contextmenu", function (e) { e.preventDefault(); });
    c.addEventListener("mousedown", function (e) {
      drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey };
      e.preventDefault();
    });
    window.addEventListener("mouseup", function () { drag = null; });
    window.addEventListener("mousemove", function (e) {
      if (!drag) return;
      var dx = e.clientX - drag.x, dy = e.clientY - drag.y;
      drag.x = e.clientX; drag.y = e.clientY;
      var cam = self.cam;
      if (drag.pan) {
        var k = cam.dist * 0.0015;
        var right = [-Math.sin(cam.yaw), Math.cos(cam.yaw), 0];
        var sp = Math.sin(cam.pitch), cp = Math.cos(cam.pitch);
        var up = [-sp * Math.cos(cam.yaw), -sp * Math.sin(cam.yaw), cp];
        for (var i = 0; i < 3; i++) cam.target[i] += -dx * k * right[i] + dy * k * up[i];
      } else {
        cam.yaw -= dx * 0.008;
        cam.pitch = Math.max(-1.55, Math.min(1.55, cam.pitch + dy * 0.008));
      }
      self.redraw();
    });
    c.addEventListener("wheel", function (e) {
      e.preventDefault();
      self.cam.dist *= Math.exp(e.deltaY * 0.0012);
      self.redraw();
    }, { passive: false });
    c.addEventListener("dblclick", function () {
      self.cam = Object.assign({}, self.home, { target: self.home.target.slice() });
      self.redraw();
    });
    window.addEventListener("resize", function () { self.redraw(); });
  };

  function message(canvas, text) {
    var div = document.createElement("div");
    div.className = "message";
    div.textContent = text;
    canvas.replaceWith(div);
  }

  // ---- 2-D plots -------------------------------------------------------------
  function niceTicks(lo, hi, n) {
    var span = hi - lo;
    if (!(span > 0)) return [lo];
    var step = Math.pow(10, Math.floor(Math.log10(span / n)));
    var err = span / n / step;
    if (err >= 7.5) step *= 10; else if (err >= 3.5) step *= 5; else if (err >= 1.5) step *= 2;
    var out = [];
    for (var v = Math.ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step) out.push(Math.abs(v) < 1e-12 * step ? 0 : v);
    return out;
  }
  // spec: {xlabel, ylabel, logy, series: [{kind: "points"|"line", x, y, color, size, label}],
  //        bars: {edges, counts, color, label}, vspans: [{x0, x1, color, label}],
  //        vlines / hlines: [{v, color, dash, label}], empty: "text"}
  function plot2d(canvas, spec) {
    var dpr = window.devicePixelRatio || 1;
    var W = Math.max(1, Math.round(canvas.clientWidth * dpr)), H = Math.max(1, Math.round(canvas.clientHeight * dpr));
    canvas.width = W; canvas.height = H;
    var ctx = canvas.getContext("2d");
    ctx.scale(dpr, dpr);
    var w = W / dpr, h = H / dpr;
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, w, h);
    ctx.font = "12px system-ui, 'DejaVu Sans', sans-serif";
    if (spec.empty) {
      ctx.fillStyle = "#5f6b7a"; ctx.textAlign = "center";
      ctx.fillText(spec.empty, w / 2, h / 2);
      return;
    }
    var L = 64, R = 14, T = 12, B = 42;
    var xs = [], ys = [];
    (spec.series || []).forEach(function (s) {
      for (var i = 0; i < s.x.length; i++) {
        if (isFinite(s.x[i]) && isFinite(s.y[i]) && (!spec.logy || s.y[i] > 0)) { xs.push(s.x[i]); ys.push(s.y[i]); }
      }
    });
    if (spec.bars) {
      xs.push(spec.bars.edges[0], spec.bars.edges[spec.bars.edges.length - 1]);
      ys.push(0, extent(spec.bars.counts)[1]);
    }
    (spec.hlines || []).forEach(function (l) { if (isFinite(l.v)) ys.push(l.v); });
    if (!xs.length) { plot2d(canvas, { empty: "nothing to draw" }); return; }
    var ex = extent(xs), x0 = ex[0], x1 = ex[1];
    var ty = spec.logy ? function (v) { return Math.log10(v); } : function (v) { return v; };
    var ey = extent(ys.map(ty)), ylo = ey[0], yhi = ey[1];
    if (spec.yzero && !spec.logy) ylo = Math.min(0, ylo);
    if (x1 === x0) { x0 -= 0.5; x1 += 0.5; }
    if (yhi === ylo) { ylo -= 0.5; yhi += 0.5; }
    var pad = 0.04 * (yhi - ylo); yhi += pad; if (!(spec.yzero && ylo === 0)) ylo -= pad;
    var px = function (v) { return L + (v - x0) / (x1 - x0) * (w - L - R); };
    var py = function (v) { return T + (yhi - ty(v)) / (yhi - ylo) * (h - T - B); };
    // spans
    (spec.vspans || []).forEach(function (s) {
      ctx.fillStyle = s.color;
      var a = Math.max(L, px(s.x0)), b = Math.min(w - R, px(s.x1));
      if (b > a) ctx.fillRect(a, T, b - a, h - T - B);
    });
    // grid and ticks
    ctx.strokeStyle = "#e3e8ee"; ctx.fillStyle = "#3b4552"; ctx.lineWidth = 1;
    ctx.textAlign = "center"; ctx.textBaseline = "top";
    niceTicks(x0, x1, 8).forEach(function (v) {
      var x = px(v);
      ctx.beginPath(); ctx.moveTo(x, T); ctx.lineTo(x, h - B); ctx.stroke();
      ctx.fillText(fmt(v), x, h - B + 4);
    });
    ctx.textAlign = "right"; ctx.textBaseline = "middle";
    var yt = spec.logy ? (function () {
      var out = [];
      for (var e = Math.floor(ylo); e <= Math.ceil(yhi); e++) [1, 2, 5].forEach(function (m) {
        var v = Math.log10(m) + e;
        if (v >= ylo && v <= yhi && (m === 1 || yhi - ylo < 3)) out.push(v);
      });
      // Less than a decade shown: linear ticks placed on the log axis.
      if (out.length < 3) {
        out = niceTicks(Math.pow(10, ylo), Math.pow(10, yhi), 6)
          .filter(function (v) { return v > 0; })
          .map(function (v) { return Math.log10(v); });
      }
      return out;
    })() : niceTicks(ylo, yhi, 6);
    yt.forEach(function (v) {
      var y = T + (yhi - v) / (yhi - ylo) * (h - T - B);
      ctx.beginPath(); ctx.moveTo(L, y); ctx.lineTo(w - R, y); ctx.stroke();
      ctx.fillText(fmt(spec.logy ? Math.pow(10, v) : v), L - 6, y);
    });
    ctx.save();
    ctx.beginPath(); ctx.rect(L, T, w - L - R, h - T - B); ctx.clip();
    if (spec.bars) {
      var e = spec.bars.edges;
      ctx.fillStyle = spec.bars.color;
      spec.bars.counts.forEach(function (c, i) {
        var a = px(e[i]), b = px(e[i + 1]), y = py(c);
        ctx.fillRect(a + 0.5, y, Math.max(0.5, b - a - 1), py(0) - y);
      });
    }
    (spec.series || []).forEach(function (s) {
      ctx.fillStyle = s.color; ctx.strokeStyle = s.color;
      if (s.kind === "line") {
        ctx.lineWidth = s.width || 1.2;
        ctx.beginPath();
        var on = false;
        for (var i = 0; i < s.x.length; i++) {
          var ok = isFinite(s.x[i]) && isFinite(s.y[i]) && (!spec.logy || s.y[i] > 0);
          if (!ok) { on = false; continue; }
          if (on) ctx.lineTo(px(s.x[i]), py(s.y[i])); else ctx.moveTo(px(s.x[i]), py(s.y[i]));
          on = true;
        }
        ctx.stroke();
      } else {
        var r = s.size || 2;
        for (var j = 0; j < s.x.length; j++) {
          if (!(isFinite(s.x[j]) && isFinite(s.y[j]) && (!spec.logy || s.y[j] > 0))) continue;
          ctx.fillRect(px(s.x[j]) - r / 2, py(s.y[j]) - r / 2, r, r);
        }
      }
    });
    function lines(list, vertical) {
      (list || []).forEach(function (l) {
        if (!isFinite(l.v) || (spec.logy && !vertical && l.v <= 0)) return;
        ctx.strokeStyle = l.color; ctx.lineWidth = 1.4;
        ctx.setLineDash(l.dash ? [6, 4] : []);
        ctx.beginPath();
        if (vertical) { ctx.moveTo(px(l.v), T); ctx.lineTo(px(l.v), h - B); } else { ctx.moveTo(L, py(l.v)); ctx.lineTo(w - R, py(l.v)); }
        ctx.stroke();
      });
      ctx.setLineDash([]);
    }
    lines(spec.vlines, true);
    lines(spec.hlines, false);
    ctx.restore();
    ctx.strokeStyle = "#8a96a3"; ctx.lineWidth = 1; ctx.strokeRect(L, T, w - L - R, h - T - B);
    ctx.fillStyle = "#1d232b"; ctx.textAlign = "center"; ctx.textBaseline = "bottom";
    ctx.fillText(spec.xlabel || "", L + (w - L - R) / 2, h - 4);
    ctx.save(); ctx.translate(14, T + (h - T - B) / 2); ctx.rotate(-Math.PI / 2);
    ctx.textBaseline = "middle"; ctx.fillText(spec.ylabel || "", 0, 0); ctx.restore();
    // legend
    var items = [];
    (spec.vspans || []).concat(spec.series || [], spec.bars ? [spec.bars] : [], spec.hlines || [], spec.vlines || [])
      .forEach(function (it) { if (it.label) items.push(it); });
    if (items.length) {
      ctx.textAlign = "left"; ctx.textBaseline = "middle";
      var lw = 0;
      items.forEach(function (it) { lw = Math.max(lw, ctx.measureText(it.label).width); });
      var bx = w - R - lw - 34, by = T + 6;
      ctx.fillStyle = "rgba(255,255,255,0.85)";
      ctx.fillRect(bx - 6, by - 4, lw + 36, items.length * 16 + 6);
      items.forEach(function (it, i) {
        var y = by + 6 + i * 16;
        ctx.fillStyle = it.color; ctx.strokeStyle = it.color;
        if (it.v !== undefined) { ctx.setLineDash(it.dash ? [4, 3] : []); ctx.beginPath(); ctx.moveTo(bx, y); ctx.lineTo(bx + 20, y); ctx.stroke(); ctx.setLineDash([]); }
        else ctx.fillRect(bx + 4, y - 4, 12, 8);
        ctx.fillStyle = "#1d232b"; ctx.fillText(it.label, bx + 26, y);
      });
    }
  }

  // ---- the figures -----------------------------------------------------------
  var data = JSON.parse(document.getElementById("s2w-data").textContent);
  var F = data.figures, R = data.report;
  var origin = F.origin;
  var ape = R.ape || null;
  var pairs = F.pairs;
  // Times on the plots: seconds since the first matched pair.
  var t0 = pairs.t.length ? pairs.t[0] : 0;
  var trel = pairs.t.map(function (x) { return x - t0; });

  function local(path) {
    var out = new Float32Array(path.xyz.length * 3);
    path.xyz.forEach(function (p, i) {
      out[3 * i] = p[0] - origin[0]; out[3 * i + 1] = p[1] - origin[1]; out[3 * i + 2] = p[2] - origin[2];
    });
    return out;
  }
  function bounds(xyz, robust) {
    var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    if (robust && xyz.length > 3000) {
      for (var k = 0; k < 3; k++) {
        var col = [];
        var step = Math.max(1, Math.floor(xyz.length / 3 / 20000));
        for (var i = k; i < xyz.length; i += 3 * step) col.push(xyz[i]);
        lo[k] = quantile(col, 0.005); hi[k] = quantile(col, 0.995);
      }
      return [lo, hi];
    }
    for (var j = 0; j < xyz.length; j += 3) {
      for (var a = 0; a < 3; a++) {
        if (isFinite(xyz[j + a])) { lo[a] = Math.min(lo[a], xyz[j + a]); hi[a] = Math.max(hi[a], xyz[j + a]); }
      }
    }
    return [lo, hi];
  }
  function merge(a, b) {
    return [[0, 1, 2].map(function (k) { return Math.min(a[0][k], b[0][k]); }), [0, 1, 2].map(function (k) { return Math.max(a[1][k], b[1][k]); })];
  }
  function solid(n, c) {
    var out = new Float32Array(3 * n);
    for (var i = 0; i < n; i++) { out[3 * i] = c[0]; out[3 * i + 1] = c[1]; out[3 * i + 2] = c[2]; }
    return out;
  }
  var GREY = [0.62, 0.66, 0.7];
  var ORANGE = [1.0, 0.6, 0.15];

  var est = local(F.estimate);
  var ref = F.reference ? local(F.reference) : null;
  var errExt = extent(pairs.error);
  var errLo = pairs.error.length ? errExt[0] : 0;
  var errHi = pairs.error.length ? errExt[1] : 1;
  if (!(errHi > errLo)) errHi = errLo + 1e-9;
  var drawn = [];

  function pathsFigure() {
    var canvas = document.getElementById("paths-view");
    var v = new View3D(canvas);
    var n = est.length / 3;
    var col = solid(n, GREY);
    var perr = new Float32Array(3 * pairs.error.length), pcol = new Float32Array(3 * pairs.error.length);
    pairs.slam_index.forEach(function (s, k) {
      var c = cmap(PLASMA, (pairs.error[k] - errLo) / (errHi - errLo));
      col[3 * s] = c[0]; col[3 * s + 1] = c[1]; col[3 * s + 2] = c[2];
      for (var a = 0; a < 3; a++) { perr[3 * k + a] = est[3 * s + a]; pcol[3 * k + a] = c[a]; }
    });
    var b = bounds(est);
    if (ref) {
      v.add("line", ref, solid(ref.length / 3, [0.8, 0.82, 0.85]));
      b = merge(b, bounds(ref));
    }
    v.add("line", est, col);
    v.add("points", perr, pcol, null, { size: 4 });
    v.frame(b[0], b[1]);
    v.draw();
    colorbar(document.getElementById("paths-colorbar"), PLASMA, errLo, errHi, "error of the pair (m)");
    drawn.push("paths");
  }

  function pkFigure() {
    var canvas = document.getElementById("pk-plot");
    var p = F.scale_factors;
    if (!p.length) { plot2d(canvas, { empty: "no scale factors (no matched pairs with a reference)" }); drawn.push("p_k"); return; }
    var t = p.map(function (_, k) { return trel[k + 1]; });
    var st = F.stages;
    var spans = [], series = [];
    if (st) {
      var tc = trel[st.converging_start + 1], ts = trel[st.stable_start + 1];
      var used = st.used_by_fit ? "" : " (not cut)";
      spans.push({ x0: t[0] - 1e9, x1: tc, color: "rgba(214,39,40,0.10)", label: "1: start-up" + used });
      spans.push({ x0: tc, x1: ts, color: "rgba(255,127,14,0.16)", label: "2: converging" + used });
      spans.push({ x0: ts, x1: t[t.length - 1] + 1e9, color: "rgba(44,160,44,0.10)", label: "3: stable" });
    }
    var fitted = { kind: "points", x: [], y: [], color: "#1d232b", size: 3, label: "p_k, both pairs fitted" };
    var other = { kind: "points", x: [], y: [], color: "#d62728", size: 3, label: "p_k, a pair not fitted" };
    p.forEach(function (v, k) {
      var s = pairs.fitted[k] && pairs.fitted[k + 1] ? fitted : other;
      s.x.push(t[k]); s.y.push(v);
    });
    series.push(fitted, other);
    var h = [];
    if (st) h.push({ v: st.stable_level, color: "#2ca02c", label: "stable level " + fmt(st.stable_level) });
    var sc = R.t_world_slam ? R.t_world_slam.scale : R.scale;
    if (sc) h.push({ v: sc * sc, color: "#1f77b4", dash: true, label: "fitted s² " + fmt(sc * sc) });
    plot2d(canvas, { xlabel: "time of the later pair since the first pair (s)", ylabel: "p_k = |Δref|² / |Δslam|²", logy: true, series: series, vspans: spans, hlines: h });
    drawn.push("p_k");
  }

  function errorFigures() {
    var c1 = document.getElementById("error-plot"), c2 = document.getElementById("hist-plot");
    if (!pairs.error.length) {
      plot2d(c1, { empty: "no matched pairs" }); plot2d(c2, { empty: "no matched pairs" });
      drawn.push("error", "histogram"); return;
    }
    var fit = { kind: "points", x: [], y: [], color: "#1f6feb", size: 3, label: "fitted pair" };
    var out = { kind: "points", x: [], y: [], color: "#d62728", size: 3, label: "not fitted" };
    pairs.error.forEach(function (e, k) { var s = pairs.fitted[k] ? fit : out; s.x.push(trel[k]); s.y.push(e); });
    var line = { kind: "line", x: trel, y: pairs.error, color: "rgba(31,111,235,0.35)", width: 1 };
    var stats = ape ? [
      { v: ape.rmse, color: "#d62728", label: "rmse " + fmt(ape.rmse) },
      { v: ape.median, color: "#2ca02c", dash: true, label: "median " + fmt(ape.median) },
      { v: ape.mean, color: "#9467bd", dash: true, label: "mean " + fmt(ape.mean) }
    ] : [];
    plot2d(c1, { xlabel: "time since the first pair (s)", ylabel: "APE (m)", yzero: true, series: [line, fit, out], hlines: stats });
    var hi = quantile(pairs.error, 0.995);
    if (!(hi > 0)) hi = errHi;
    var nb = 40, edges = [], counts = [];
    for (var i = 0; i <= nb; i++) edges.push(hi * i / nb);
    for (var j = 0; j < nb; j++) counts.push(0);
    pairs.error.forEach(function (e) { counts[Math.min(nb - 1, Math.max(0, Math.floor(e / hi * nb)))] += 1; });
    plot2d(c2, { xlabel: "APE (m)", ylabel: "pairs", yzero: true, bars: { edges: edges, counts: counts, color: "#7aa6e8", label: "pairs" }, vlines: stats });
    drawn.push("error", "histogram");
  }

  function heightsFigure() {
    var section = document.getElementById("heights-section");
    var p = R.prior;
    if (!p || !p.heights || !p.heights.length) { section.style.display = "none"; return; }
    var t0 = p.heights[0][0];
    var x = p.heights.map(function (h) { return h[0] - t0; });
    var y = p.heights.map(function (h) { return h[1]; });
    var series = [
      { kind: "line", x: x, y: y, color: "rgba(31,111,235,0.45)", width: 1 },
      { kind: "points", x: x, y: y, color: "#1f6feb", size: 3, label: "height over the ground plane" }
    ];
    var h = [];
    var ch = p.camera_height;
    if (ch && (ch.kind === "constant" || ch.kind === "first")) {
      h.push({ v: ch.metres, color: "#d62728", dash: true, label: (ch.kind === "first" ? "given at the first pose: " : "given: ") + fmt(ch.metres) + " m" });
    }
    plot2d(document.getElementById("heights-plot"), { xlabel: "time since the first pose (s)", ylabel: "height (m)", yzero: true, series: series, hlines: h });
    drawn.push("heights");
  }

  function profileFigure() {
    var section = document.getElementById("profile-section");
    var p = R.prior;
    var w = p && p.profile ? p.profile.filter(function (v) { return v.scale !== null; }) : [];
    if (!w.length) { section.style.display = "none"; return; }
    var t0 = p.heights.length ? p.heights[0][0] : w[0].time;
    var x = w.map(function (v) { return v.time - t0; });
    var y = w.map(function (v) { return 100 * (v.scale / p.scale - 1); });
    var series = [
      { kind: "line", x: x, y: y, color: "rgba(44,160,44,0.45)", width: 1 },
      { kind: "points", x: x, y: y, color: "#2ca02c", size: 4, label: "window's scale against the run's" }
    ];
    var h = [{ v: 0, color: "#555", dash: true, label: "the run's scale" }];
    if (p.scale_sigma !== null && p.scale_sigma !== undefined) {
      h.push({ v: 100 * p.scale_sigma, color: "#d62728", dash: true, label: "± its sigma" });
      h.push({ v: -100 * p.scale_sigma, color: "#d62728", dash: true });
    }
    var missing = p.profile.length - w.length;
    document.getElementById("profile-caption").textContent = w.length + " windows of " + (w[0].last - w[0].first + 1) + " keyframes" + (missing ? ", " + missing + " without the ground" : "");
    plot2d(document.getElementById("profile-plot"), { xlabel: "time since the first pose (s)", ylabel: "scale (%)", series: series, hlines: h });
    drawn.push("profile");
  }

  // A square grid in the ground plane `g` (normal, point: offsets from the
  // origin) over the bounds `b`, as one line strip (the turns on its border).
  function groundGrid(g, b) {
    var n = norm(g.normal);
    var u = norm(cross(n, Math.abs(n[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0])), w = cross(n, u);
    var c = [0, 1, 2].map(function (a) { return 0.5 * (b[0][a] + b[1][a]); });
    var d = dot(sub(c, g.point), n);
    c = [c[0] - d * n[0], c[1] - d * n[1], c[2] - d * n[2]];
    var h = 0.5 * Math.max(b[1][0] - b[0][0], b[1][1] - b[0][1], b[1][2] - b[0][2]) || 1;
    var k = 10, out = [];
    function at(s, t) { for (var a = 0; a < 3; a++) out.push(c[a] + s * u[a] + t * w[a]); }
    for (var i = 0; i <= k; i++) { var s = -h + 2 * h * i / k; if (i % 2) { at(s, h); at(s, -h); } else { at(s, -h); at(s, h); } }
    for (var j = 0; j <= k; j++) { var t = h - 2 * h * j / k; if (j % 2) { at(-h, t); at(h, t); } else { at(h, t); at(-h, t); } }
    return new Float32Array(out);
  }

  function cloudFigure() {
    var section = document.getElementById("cloud-section");
    if (!F.cloud && !F.voxels) { section.style.display = "none"; return; }
    var canvas = document.getElementById("cloud-view");
    var v = new View3D(canvas);
    var xyz = F.cloud ? floats(F.cloud.xyz) : new Float32Array(0);
    var n = xyz.length / 3;
    var b = n ? bounds(xyz, true) : bounds(est);
    var zlo = b[0][2], zhi = b[1][2];
    if (!(zhi > zlo)) zhi = zlo + 1;
    var heightCol = new Float32Array(3 * n);
    for (var i = 0; i < n; i++) {
      var c = cmap(VIRIDIS, (xyz[3 * i + 2] - zlo) / (zhi - zlo));
      heightCol[3 * i] = c[0]; heightCol[3 * i + 1] = c[1]; heightCol[3 * i + 2] = c[2];
    }
    var imageCol = null;
    if (F.cloud && F.cloud.rgb) {
      var rgb = bytes(F.cloud.rgb);
      imageCol = new Float32Array(rgb.length);
      for (var k = 0; k < rgb.length; k++) imageCol[k] = rgb[k] / 255;
    }
    var pts = v.add("points", xyz, heightCol);
    var ptsImage = imageCol ? v.add("points", xyz, imageCol) : null;
    if (ptsImage) ptsImage.visible = false;
    var vox = null;
    if (F.voxels && F.voxels.n) {
      var ctr = floats(F.voxels.center), edge = floats(F.voxels.size);
      var vc = new Float32Array(ctr.length);
      for (var j = 0; j < edge.length; j++) {
        var cc = cmap(VIRIDIS, (ctr[3 * j + 2] - zlo) / (zhi - zlo));
        vc[3 * j] = cc[0]; vc[3 * j + 1] = cc[1]; vc[3 * j + 2] = cc[2];
      }
      vox = v.add("cubes", ctr, vc, edge);
      vox.visible = false;
      if (!n) b = bounds(ctr);
    }
    var paths = [];
    if (ref) paths.push(v.add("line", ref, solid(ref.length / 3, [0.85, 0.87, 0.9])));
    paths.push(v.add("line", est, solid(est.length / 3, ORANGE)));
    var ground = null;
    if (F.ground) {
      var grid = groundGrid(F.ground, b);
      ground = v.add("line", grid, solid(grid.length / 3, [0.55, 0.7, 0.55]));
    }
    var groundBox = document.getElementById("show-ground");
    if (!ground) { groundBox.checked = false; groundBox.disabled = true; groundBox.parentNode.title = "no ground plane in this conversion"; }
    v.frame(b[0], b[1]);
    var colourSel = document.getElementById("cloud-colour");
    if (!imageCol) { colourSel.querySelector("option[value=image]").disabled = true; }
    function update() {
      var showPts = document.getElementById("show-points").checked;
      var byImage = colourSel.value === "image" && ptsImage;
      pts.visible = showPts && !byImage;
      if (ptsImage) ptsImage.visible = showPts && !!byImage;
      if (vox) vox.visible = document.getElementById("show-voxels").checked;
      paths.forEach(function (p) { p.visible = document.getElementById("show-paths").checked; });
      if (ground) ground.visible = groundBox.checked;
      v.pointSize = Number(document.getElementById("point-size").value);
      v.redraw();
    }
    ["cloud-colour", "show-voxels", "show-points", "show-paths", "show-ground", "point-size"].forEach(function (id) {
      document.getElementById(id).addEventListener("input", update);
      document.getElementById(id).addEventListener("change", update);
    });
    var voxBox = document.getElementById("show-voxels");
    if (!vox) { voxBox.disabled = true; voxBox.parentNode.title = "no octree in this conversion"; }
    v.draw();
    colorbar(document.getElementById("cloud-colorbar"), VIRIDIS, zlo + origin[2], zhi + origin[2], "height z (m)");
    var cap = [];
    if (F.cloud) cap.push(F.cloud.n + " of " + F.cloud.n_total + " points" + (F.cloud.stride > 1 ? " (every " + F.cloud.stride + "th)" : ""));
    if (F.voxels) cap.push(F.voxels.n + " occupied voxels (" + fmt(F.voxels.resolution) + " m octree)");
    document.getElementById("cloud-caption").textContent = cap.join(", ");
    window.s2wCloudView = v;
    drawn.push("cloud");
  }

  [["paths", pathsFigure], ["p_k", pkFigure], ["errors", errorFigures], ["heights", heightsFigure], ["profile", profileFigure], ["cloud", cloudFigure]].forEach(function (f) {
    try { f[1](); } catch (e) {
      fail(f[0], e);
      var el = document.getElementById(f[0] === "cloud" ? "cloud-view" : f[0] === "paths" ? "paths-view" : null);
      if (el) message(el, "could not draw: " + (e && e.message ? e.message : e));
    }
  });
  statusEl.textContent = problems.length ? "errors: " + problems.join("; ") : "drawn: " + drawn.join(", ");
  if (problems.length) statusEl.className = "status error";
  document.body.setAttribute("data-ready", problems.length ? "error" : "1");
  window.s2wReady = true;
})();
