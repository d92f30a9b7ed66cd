// The 3D view of an episode in report.html (dips-report, scene3d.rs): draws the scene data
// (positions computed in Rust from our kinematics) with three.js (the global DIPS_THREE,
// inflated first from the page's gzip-compressed base64 copy), turned with OrbitControls,
// one state at a time chosen by the slider or played.
// window.dipsScene is a small hook for people and tests (scripts/check-report-3d.sh).
(function () {
  'use strict';
  var root = document.getElementById('dips-scene');
  var view = document.getElementById('dips-scene-view');
  var slider = document.getElementById('dips-scene-slider');
  var playButton = document.getElementById('dips-scene-play');
  var resetButton = document.getElementById('dips-scene-reset');
  var label = document.getElementById('dips-scene-label');
  var data = JSON.parse(document.getElementById('dips-scene-data').textContent);
  var T = window.DIPS_THREE;
  var hook = { ready: false, error: null, renders: 0, frameCount: data.frames.length };
  window.dipsScene = hook;

  function fail(message) {
    hook.error = message;
    root.setAttribute('data-error', message);
    var p = document.createElement('p');
    p.className = 'note';
    p.textContent = '3D view unavailable: ' + message;
    view.appendChild(p);
  }

  // three.js: base64 → gzip → the script that defines DIPS_THREE, run as an inline script.
  function loadThree(done) {
    if (T) return done();
    var packed = document.getElementById('dips-three-gz');
    if (!packed) return fail('three.js is missing from the page');
    if (typeof DecompressionStream === 'undefined') {
      return fail('this browser cannot inflate the embedded three.js (no DecompressionStream)');
    }
    var bin = atob(packed.textContent.trim());
    var bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    var inflated = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('gzip'));
    new Response(inflated).text().then(function (source) {
      var script = document.createElement('script');
      script.textContent = source;
      document.head.appendChild(script); // runs now, defining DIPS_THREE
      T = window.DIPS_THREE;
      if (!T) return fail('three.js did not load');
      done();
    }, function (e) {
      fail('the embedded three.js could not be inflated (' + e + ')');
    });
  }
  loadThree(start);

  function start() {
    var renderer;
    try {
      renderer = new T.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    } catch (e) {
      fail('this browser has no WebGL (' + e.message + ')');
      return;
    }
    renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    renderer.outputColorSpace = T.SRGBColorSpace;
    view.appendChild(renderer.domElement);

    var scene = new T.Scene();
    scene.background = new T.Color(0xf7f7f5);
    scene.add(new T.HemisphereLight(0xffffff, 0x8a8a80, 1.6));
    var sun = new T.DirectionalLight(0xffffff, 1.6);
    sun.position.set(0.6, -1.0, 2.0);
    scene.add(sun);

    var camera = new T.PerspectiveCamera(35, 1, 0.002, 50);
    camera.up.set(0, 0, 1); // the world's z is up
    var controls = new T.OrbitControls(camera, renderer.domElement);

    function mat(color, opacity) {
      var m = new T.MeshStandardMaterial({ color: color, roughness: 0.6, metalness: 0.05 });
      if (opacity !== undefined && opacity < 1) {
        m.transparent = true;
        m.opacity = opacity;
        m.depthWrite = false;
        m.polygonOffset = true; // behind the object where they coincide: no z-fighting
        m.polygonOffsetFactor = 2;
        m.polygonOffsetUnits = 2;
      }
      return m;
    }
    function partMesh(p, material) {
      var g;
      if (p.shape === 'box') {
        g = new T.BoxGeometry(2 * p.half[0], 2 * p.half[1], 2 * p.half[2]);
        g.translate(p.center[0], p.center[1], p.center[2]);
      } else {
        g = new T.CylinderGeometry(p.radius, p.radius, p.z1 - p.z0, 40);
        g.rotateX(Math.PI / 2); // three's cylinders run along y; ours along the body's z
        g.translate(0, 0, (p.z0 + p.z1) / 2);
      }
      return new T.Mesh(g, material);
    }
    function line(points, color, dashed) {
      var g = new T.BufferGeometry();
      var flat = [];
      points.forEach(function (p) { flat.push(p[0], p[1], p[2]); });
      g.setAttribute('position', new T.Float32BufferAttribute(flat, 3));
      var m = dashed
        ? new T.LineDashedMaterial({ color: color, dashSize: 0.004, gapSize: 0.003 })
        : new T.LineBasicMaterial({ color: color });
      var l = new T.Line(g, m);
      if (dashed) l.computeLineDistances();
      return l;
    }
    function setPose(obj, pose) {
      obj.position.set(pose[0], pose[1], pose[2]);
      obj.quaternion.set(pose[3], pose[4], pose[5], pose[6]);
    }
    function objectGroup(material, markerColor, dashed) {
      var g = new T.Group();
      data.object.forEach(function (p) {
      var m = partMesh(p, material);
      g.add(m);
      if (dashed) {
        // A goal: the outline, over a faint fill drawn behind coplanar faces.
        var edges = new T.LineSegments(new T.EdgesGeometry(m.geometry, 25),
          new T.LineBasicMaterial({ color: 0x111111 }));
        g.add(edges);
      }
    });
      if (data.marker) {
        // Half a millimetre above the cap, so that the cap's face does not hide it.
        g.add(line(data.marker.map(function (p) { return [p[0], p[1], p[2] + 0.0005]; }),
          markerColor, dashed));
        var dot = new T.Mesh(new T.SphereGeometry(0.0025, 12, 8), mat(markerColor));
        dot.position.set(data.marker[1][0], data.marker[1][1], data.marker[1][2] + 0.0005);
        g.add(dot);
      }
      return g;
    }

    // The table and the object.
    if (data.table) scene.add(partMesh(data.table, mat(0xb9b9b4)));
    var object = objectGroup(mat(0xcd7814), 0xc8005a, false);
    scene.add(object);
    var goals = data.goals.map(function (goal) {
      var g = objectGroup(mat(0x222222, 0.14), 0x000000, true);
      setPose(g, goal.pose);
      g.visible = false;
      scene.add(g);
      return g;
    });

    // The hand: a cylinder per link segment, a ball per joint, the fingertip spheres.
    var P = data.fingers.length ? data.frames[0].hand.length / (3 * data.fingers.length) : 0;
    var unitY = new T.Vector3(0, 1, 0);
    var linkGeometry = new T.CylinderGeometry(1, 1, 1, 16);
    var jointGeometry = new T.SphereGeometry(1, 16, 12);
    var linkR = 0.45 * data.tip_radius;
    var segments = [];
    var joints = [];
    var tips = [];
    data.fingers.forEach(function (f) {
      var m = mat(f.color);
      var palm = mat(0x8c8c96);
      for (var k = 0; k + 1 < P; k++) {
        var s = new T.Mesh(linkGeometry, k === 0 ? palm : m);
        scene.add(s);
        segments.push({ mesh: s, r: k === 0 ? 0.4 * linkR : linkR });
      }
      for (var j = 1; j + 1 < P; j++) {
        var b = new T.Mesh(jointGeometry, m);
        b.scale.setScalar(1.1 * linkR);
        scene.add(b);
        joints.push(b);
      }
      var tip = new T.Mesh(jointGeometry, mat(f.color, f.task ? 1 : 0.85));
      tip.scale.setScalar(data.tip_radius);
      scene.add(tip);
      tips.push(tip);
    });
    var a = new T.Vector3();
    var b = new T.Vector3();
    var d = new T.Vector3();
    function point(hand, i, out) {
      return out.set(hand[3 * i], hand[3 * i + 1], hand[3 * i + 2]);
    }

    // Paths up to the shown state: the task fingertips and the object's reference point.
    var paths = [];
    var refLocal = new T.Vector3(data.reference[0], data.reference[1], data.reference[2]);
    data.fingers.forEach(function (f, i) {
      if (!f.task) return;
      var pts = data.frames.map(function (fr) {
        var t = 3 * (i * P + P - 1);
        return [fr.hand[t], fr.hand[t + 1], fr.hand[t + 2]];
      });
      paths.push(line(pts, 0xaa3caa, false));
    });
    paths.push(line(data.frames.map(function (fr) {
      var q = new T.Quaternion(fr.object[3], fr.object[4], fr.object[5], fr.object[6]);
      var p = refLocal.clone().applyQuaternion(q);
      return [p.x + fr.object[0], p.y + fr.object[1], p.z + fr.object[2]];
    }), 0xaa3caa, false));
    paths.forEach(function (l) { scene.add(l); });

    // Contacts and forces, from a pool.
    var contactGeometry = new T.SphereGeometry(0.0022, 12, 8);
    // Drawn over everything (as in the three-view drawings): a contact sits on a fingertip's
    // surface and its force points into the object, where they would be hidden.
    var contactMaterial = new T.MeshBasicMaterial({ color: 0xd21414, depthTest: false });
    var pool = [];
    function contactAt(n) {
      while (pool.length <= n) {
        var dot = new T.Mesh(contactGeometry, contactMaterial);
        var arrow = new T.ArrowHelper(unitY, new T.Vector3(), 0.01, 0x149628, 0.004, 0.0025);
        dot.renderOrder = 10;
        arrow.line.material.depthTest = false;
        arrow.cone.material.depthTest = false;
        arrow.renderOrder = 11;
        arrow.line.renderOrder = 11;
        arrow.cone.renderOrder = 11;
        scene.add(dot);
        scene.add(arrow);
        pool.push({ dot: dot, arrow: arrow });
      }
      return pool[n];
    }

    var current = -1;
    function render() {
      renderer.render(scene, camera);
      hook.renders++;
      root.setAttribute('data-renders', String(hook.renders));
    }
    // Turning the view asks for many renders a frame: one per animation frame is enough.
    var pending = false;
    function requestRender() {
      if (pending) return;
      pending = true;
      requestAnimationFrame(function () {
        pending = false;
        render();
      });
    }

    function show(k) {
      k = Math.max(0, Math.min(data.frames.length - 1, k | 0));
      var fr = data.frames[k];
      current = k;
      var h = fr.hand;
      var si = 0;
      var ji = 0;
      for (var f = 0; f < data.fingers.length; f++) {
        for (var i = 0; i + 1 < P; i++) {
          point(h, f * P + i, a);
          point(h, f * P + i + 1, b);
          var seg = segments[si++];
          d.subVectors(b, a);
          var len = d.length();
          seg.mesh.position.addVectors(a, b).multiplyScalar(0.5);
          if (len > 1e-9) seg.mesh.quaternion.setFromUnitVectors(unitY, d.divideScalar(len));
          seg.mesh.scale.set(seg.r, Math.max(len, 1e-6), seg.r);
          if (i >= 1) joints[ji++].position.copy(a);
        }
        point(h, f * P + P - 1, tips[f].position);
      }
      setPose(object, fr.object);
      goals.forEach(function (g, i) { g.visible = fr.goals.indexOf(i) >= 0; });
      paths.forEach(function (l) { l.geometry.setDrawRange(0, k + 1); });
      pool.forEach(function (c) { c.dot.visible = false; c.arrow.visible = false; });
      fr.contacts.forEach(function (c, n) {
        var slot = contactAt(n);
        slot.dot.position.set(c[0], c[1], c[2]);
        slot.dot.visible = true;
        d.set(c[3], c[4], c[5]);
        var len = d.length() * data.force_scale;
        if (len > 1e-6) {
          slot.arrow.position.set(c[0], c[1], c[2]);
          slot.arrow.setDirection(d.normalize());
          slot.arrow.setLength(len, Math.min(0.004, 0.4 * len), Math.min(0.0025, 0.25 * len));
          slot.arrow.visible = true;
        }
      });
      slider.value = String(k);
      root.setAttribute('data-frame', String(k));
      root.setAttribute('data-tips', JSON.stringify(hook.stepPositions()));
      label.textContent = fr.label + (fr.goals.length
        ? ' · ghost: ' + fr.goals.map(function (i) { return data.goals[i].label; }).join(', ')
        : '');
      render();
    }

    // A camera that sees every state: the hand and the object over the whole episode.
    var box = new T.Box3();
    data.frames.forEach(function (fr) {
      for (var i = 0; 3 * i < fr.hand.length; i++) box.expandByPoint(point(fr.hand, i, a));
      box.expandByPoint(a.set(fr.object[0], fr.object[1], fr.object[2]));
    });
    var center = new T.Vector3();
    var size = new T.Vector3();
    box.getCenter(center);
    box.getSize(size);
    var radius = Math.max(0.04, 0.5 * Math.max(size.x, size.y, size.z) + 2 * data.tip_radius);
    function resetView() {
      var dist = radius / Math.sin((camera.fov * Math.PI) / 360) * 0.9;
      var dir = new T.Vector3(0.55, -1.0, 0.75).normalize();
      camera.position.copy(center).addScaledVector(dir, dist);
      controls.target.copy(center);
      camera.near = dist / 100;
      camera.far = dist * 20;
      camera.updateProjectionMatrix();
      controls.update();
      render();
    }

    function resize() {
      var w = view.clientWidth || 800;
      var h = Math.round(Math.min(620, Math.max(320, 0.6 * w)));
      renderer.setSize(w, h);
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
      if (current >= 0) render();
    }

    // Playing: each state held its time (as in the animation), by timers, which run in
    // every browser whether or not it draws animation frames.
    var playing = false;
    var timer = null;
    function setPlaying(p) {
      playing = p;
      playButton.textContent = p ? '❚❚ pause' : '▶ play';
      if (timer !== null) clearTimeout(timer);
      timer = null;
      if (p) schedule();
    }
    function schedule() {
      timer = setTimeout(function () {
        timer = null;
        if (!playing) return;
        if (current + 1 >= data.frames.length) {
          setPlaying(false);
          return;
        }
        show(current + 1);
        schedule();
      }, 1000 * (data.frames[current].hold_s || 0.4));
    }

    controls.addEventListener('change', requestRender);
    slider.addEventListener('input', function () {
      setPlaying(false);
      show(+slider.value);
    });
    playButton.addEventListener('click', function () {
      if (!playing && current + 1 >= data.frames.length) show(0);
      setPlaying(!playing);
    });
    resetButton.addEventListener('click', resetView);
    window.addEventListener('resize', resize);

    // The hook: choose a state, read back what is drawn.
    hook.setFrame = function (k) { setPlaying(false); show(k); };
    hook.frame = function () { return current; };
    hook.stepPositions = function () {
      return tips.map(function (t) { return [t.position.x, t.position.y, t.position.z]; });
    };
    hook.objectPose = function () {
      return [object.position.x, object.position.y, object.position.z,
        object.quaternion.x, object.quaternion.y, object.quaternion.z, object.quaternion.w];
    };

    // `report.html#frame=K` (or `#frame=last`) opens at state K, through the slider as a
    // person would move it.
    function applyHash() {
      var m = /frame=(\d+|last)/.exec(window.location.hash);
      if (!m) return;
      slider.value = m[1] === 'last' ? String(data.frames.length - 1) : m[1];
      slider.dispatchEvent(new Event('input'));
    }
    window.addEventListener('hashchange', applyHash);

    resize();
    resetView();
    show(0);
    applyHash();
    hook.ready = true;
    root.setAttribute('data-ready', 'true');
  }
})();
