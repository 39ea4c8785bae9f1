// Stand-ins for the mesh loaders urdf-loader imports (three's STLLoader and ColladaLoader,
// mapped here by the page's import map): the page serves no mesh files, so a URDF's mesh is
// drawn as nothing and said once on the console; its primitive shapes are drawn as usual.
"use strict";

class NoMeshLoader {
  constructor(manager) { this.manager = manager; }

  load(url, _onLoad, _onProgress, onError) {
    const e = new Error(`${url}: the page draws no meshes (only a URDF's boxes, cylinders and spheres)`);
    if (onError) onError(e); else console.warn(e.message);
  }
}

export class STLLoader extends NoMeshLoader {}
export class ColladaLoader extends NoMeshLoader {}
