// The parts of three.js that report.html's 3D view (host/report/src/scene3d.js) uses, and
// OrbitControls, exported as one global, DIPS_THREE, by scripts/vendor-three.sh.
export {
  WebGLRenderer, Scene, PerspectiveCamera, Color, AmbientLight, DirectionalLight, HemisphereLight,
  Group, Mesh, BoxGeometry, CylinderGeometry, SphereGeometry, MeshStandardMaterial, MeshBasicMaterial,
  LineBasicMaterial, LineDashedMaterial, Line, LineSegments, BufferGeometry, Float32BufferAttribute,
  Vector3, Quaternion, ArrowHelper, EdgesGeometry, SRGBColorSpace, Box3,
} from 'three';
export { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
