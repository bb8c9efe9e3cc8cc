// The entry of fenestra's vendored three.js bundle (three-viewer.min.js): the parts of three.js that
// the reconstruct folder's index.html (fenestra/pipeline/export/viewer.py) uses, as the global FenestraThree.
export { WebGLRenderer, Scene, PerspectiveCamera, HemisphereLight, DirectionalLight, MeshBasicMaterial, Box3,
         Sphere, Vector3, Color, REVISION } from 'three';
export { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
export { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
