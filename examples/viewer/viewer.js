// citylod viewer: streams a citylod tileset with CesiumJS (offline: no Ion,
// imagery from Cesium's bundled NaturalEarthII), shows a building's metadata
// on click and lets the user force one of the building's LOD models (the
// paper's interactive phase): the model's tile glb (buildings.json names it)
// shown alone with only that building's feature.
//
// URL parameters: ?tileset=<url of tileset.json> (default tileset/tileset.json).
// State for scripts and tests: window.citylod (see `state` below).
(function () {
  'use strict';

  const params = new URLSearchParams(window.location.search);
  const tilesetUrl = params.get('tileset') || 'tileset/tileset.json';
  const baseUrl = new URL(tilesetUrl, window.location.href);

  const state = (window.citylod = {
    ready: false,          // tileset loaded, camera on it, first full load done
    error: null,           // fatal error message
    loadedTiles: 0,        // tileLoad events
    maxLoadedDepth: -1,    // deepest tile loaded so far
    maxVisibleDepth: -1,   // deepest tile rendered in the last frame
    allTilesLoadedCount: 0,
    failed: [],            // tileFailed events {url, message}
    selected: null,        // {id, properties}
    forced: null,          // {id, index, ready}
  });

  const $ = (id) => document.getElementById(id);
  function setStatus(text, isError) {
    $('status').textContent = text;
    $('status').className = isError ? 'error' : '';
  }
  function fail(message) {
    state.error = message;
    setStatus(message, true);
    console.error('citylod viewer: ' + message);
  }

  if (typeof Cesium === 'undefined') {
    fail('CesiumJS not found under /cesium/: run scripts/install-node-tools.sh, then citylod serve.');
    return;
  }

  const tileDepth = (tile) => {
    let d = 0;
    for (let t = tile.parent; t; t = t.parent) ++d;
    return d;
  };
  const escapeStyle = (s) => String(s).replace(/\\/g, '\\\\').replace(/'/g, "\\'");

  let viewer, tileset, buildingsIndex = null, rootTransform = null, forcedModel = null, selectedId = null;

  async function loadIndex() {
    if (buildingsIndex) return buildingsIndex;
    const res = await fetch(new URL('buildings.json', baseUrl));
    if (!res.ok) throw new Error('buildings.json: HTTP ' + res.status);
    buildingsIndex = await res.json();
    rootTransform = Cesium.Matrix4.fromArray(buildingsIndex.root_transform);
    return buildingsIndex;
  }

  function applyStyle() {
    const conditions = [];
    if (selectedId !== null) conditions.push(["${building_id} === '" + escapeStyle(selectedId) + "'", "color('#ffd34d')"]);
    conditions.push(['true', "color('white')"]);
    const style = { color: { conditions } };
    if (state.forced) style.show = "${building_id} !== '" + escapeStyle(state.forced.id) + "'";
    tileset.style = new Cesium.Cesium3DTileStyle(style);
  }

  function showProperties(id, props, note) {
    const rows = Object.keys(props)
      .map((k) => {
        let v = props[k];
        if (typeof v === 'number' && !Number.isInteger(v)) v = v.toFixed(2);
        return '<tr><td>' + k + '</td><td>' + String(v).replace(/</g, '&lt;') + '</td></tr>';
      })
      .join('');
    $('info').className = '';
    $('info').innerHTML = (note ? '<div class="muted">' + note + '</div>' : '') + '<table>' + rows + '</table>';
  }

  async function selectBuilding(id, props) {
    selectedId = id;
    state.selected = { id, properties: props || {} };
    applyStyle();
    if (props) showProperties(id, props, 'as streamed (tile model)');
    const lod = $('lod');
    try {
      const index = await loadIndex();
      const entry = index.buildings[id];
      if (!entry || !entry.models.length) {
        lod.hidden = true;
        return;
      }
      lod.hidden = false;
      const slider = $('lod-slider');
      slider.max = String(entry.models.length - 1);
      const current = state.forced && state.forced.id === id ? state.forced.index : entry.models.length - 1;
      slider.value = String(current);
      $('lod-auto').checked = !(state.forced && state.forced.id === id);
      slider.disabled = $('lod-auto').checked;
      updateLodLabel(entry, current);
    } catch (e) {
      lod.hidden = true;
      console.warn(e);
    }
  }

  function updateLodLabel(entry, index) {
    const m = entry.models[index];
    $('lod-label').textContent = index + ' / ' + (entry.models.length - 1);
    $('lod-models').textContent =
      m.kind + ', level ' + m.level + ', step ' + m.step + ', ' + m.triangles + ' triangles, error ' + m.error_m.toFixed(2) + ' m';
  }

  function unforce() {
    if (forcedModel) {
      viewer.scene.primitives.remove(forcedModel);
      forcedModel = null;
    }
    state.forced = null;
    applyStyle();
  }

  /// Shows model `index` (0 = coarsest) of building `id` instead of the streamed
  /// one: the tile glb that holds it, with only that building's feature shown
  /// (or, in a tileset written with --building-models and a model no tile
  /// holds, the model's node of buildings/<id>.glb).
  async function forceModel(id, index) {
    const index_ = await loadIndex();
    const entry = index_.buildings[id];
    if (!entry) throw new Error('unknown building ' + id);
    if (index < 0 || index >= entry.models.length) throw new Error('model index out of range');
    const m = entry.models[index];
    const url = m.tile || (m.node && entry.glb) || null;
    if (!url) throw new Error('model ' + index + ' of ' + id + ' is in no tile');
    if (!forcedModel || state.forced.id !== id || state.forced.url !== url) {
      unforce();
      state.forced = { id, index, url, ready: false };
      const model = await Cesium.Model.fromGltfAsync({
        url: new URL(url, baseUrl).href,
        modelMatrix: rootTransform,
        // The axes of 3D Tiles content: y-up -> z-up only (Model's default
        // forwardAxis Z would add a quarter turn about the vertical).
        upAxis: Cesium.Axis.Y,
        forwardAxis: Cesium.Axis.X,
      });
      if (!state.forced || state.forced.url !== url) {
        // another call replaced this one while it loaded
        model.destroy();
        return;
      }
      forcedModel = model;
      viewer.scene.primitives.add(forcedModel);
      await new Promise((resolve) => {
        if (forcedModel.ready) resolve();
        else forcedModel.readyEvent.addEventListener(() => resolve());
      });
    }
    state.forced.index = index;
    if (m.tile) {
      forcedModel.style = new Cesium.Cesium3DTileStyle({ show: "${building_id} === '" + escapeStyle(id) + "'" });
    } else {
      for (let i = 0; i < entry.models.length; ++i) {
        const node = forcedModel.getNode(entry.models[i].node);
        if (node) node.show = i === index;
      }
    }
    state.forced.ready = true;
    applyStyle();
    if (selectedId === id) {
      $('lod-auto').checked = false;
      $('lod-slider').disabled = false;
      $('lod-slider').value = String(index);
    }
    showProperties(id, {
      building_id: id, lod_kind: m.kind, level: m.level, step: m.step, model_index: index,
      model_count: entry.models.length, height: m.height, footprint_area: entry.footprint_area,
      geometric_error: m.error_m, triangles: m.triangles,
    }, 'forced model');
    updateLodLabel(entry, index);
  }

  /// Camera `range` metres from a building's centre (for scripts and tests).
  async function flyToBuilding(id, range) {
    const index = await loadIndex();
    const entry = index.buildings[id];
    if (!entry) throw new Error('unknown building ' + id);
    const c = entry.centre;
    const centre = Cesium.Matrix4.multiplyByPoint(rootTransform, new Cesium.Cartesian3(c[0], c[1], c[2]), new Cesium.Cartesian3());
    viewer.camera.flyToBoundingSphere(new Cesium.BoundingSphere(centre, 10), {
      duration: 0,
      offset: new Cesium.HeadingPitchRange(0.4, -0.6, range || 60),
    });
    return centre;
  }

  /// Window position of a building's centre (for scripted clicks).
  async function screenPositionOf(id) {
    const index = await loadIndex();
    const c = index.buildings[id].centre;
    const p = Cesium.Matrix4.multiplyByPoint(rootTransform, new Cesium.Cartesian3(c[0], c[1], c[2]), new Cesium.Cartesian3());
    const toWindow = Cesium.SceneTransforms.worldToWindowCoordinates || Cesium.SceneTransforms.wgs84ToWindowCoordinates;
    const w = toWindow(viewer.scene, p);
    return w ? { x: w.x, y: w.y } : null;
  }

  async function main() {
    Cesium.Ion.defaultAccessToken = '';
    viewer = new Cesium.Viewer('cesium', {
      baseLayer: Cesium.ImageryLayer.fromProviderAsync(
        Cesium.TileMapServiceImageryProvider.fromUrl(Cesium.buildModuleUrl('Assets/Textures/NaturalEarthII'))),
      terrainProvider: new Cesium.EllipsoidTerrainProvider(),
      baseLayerPicker: false, geocoder: false, timeline: false, animation: false, sceneModePicker: false,
      navigationHelpButton: false, fullscreenButton: false, infoBox: false, selectionIndicator: false,
      homeButton: true, msaaSamples: 1,
    });
    viewer.scene.globe.baseColor = Cesium.Color.fromCssColorString('#5a6470');
    viewer.scene.highDynamicRange = false;
    state.viewer = viewer;

    try {
      tileset = await Cesium.Cesium3DTileset.fromUrl(tilesetUrl, { maximumScreenSpaceError: 16 });
    } catch (e) {
      fail('cannot load ' + tilesetUrl + ': ' + e);
      return;
    }
    state.tileset = tileset;
    viewer.scene.primitives.add(tileset);
    tileset.tileLoad.addEventListener((tile) => {
      ++state.loadedTiles;
      state.maxLoadedDepth = Math.max(state.maxLoadedDepth, tileDepth(tile));
    });
    tileset.tileFailed.addEventListener((e) => {
      state.failed.push({ url: e.url, message: String(e.message) });
      console.error('tile failed: ' + e.url + ': ' + e.message);
    });
    let frameDepth = -1;
    tileset.tileVisible.addEventListener((tile) => { frameDepth = Math.max(frameDepth, tileDepth(tile)); });
    viewer.scene.postRender.addEventListener(() => {
      state.maxVisibleDepth = frameDepth;
      frameDepth = -1;
    });
    tileset.allTilesLoaded.addEventListener(() => {
      ++state.allTilesLoadedCount;
      setStatus(state.loadedTiles + ' tiles loaded, deepest level ' + state.maxLoadedDepth +
        (state.failed.length ? ', ' + state.failed.length + ' failed' : ''), state.failed.length > 0);
    });
    applyStyle();

    viewer.screenSpaceEventHandler.setInputAction((click) => {
      const picked = viewer.scene.pick(click.position);
      if (picked instanceof Cesium.Cesium3DTileFeature) {
        const props = {};
        for (const k of picked.getPropertyIds()) props[k] = picked.getProperty(k);
        selectBuilding(String(props.building_id), props);
      } else if (forcedModel && picked && picked.primitive === forcedModel) {
        // the forced model stays selected
      } else {
        selectedId = null;
        state.selected = null;
        $('lod').hidden = true;
        $('info').className = 'muted';
        $('info').textContent = 'Click a building to see its metadata.';
        applyStyle();
      }
    }, Cesium.ScreenSpaceEventType.LEFT_CLICK);

    $('lod-auto').addEventListener('change', () => {
      const auto = $('lod-auto').checked;
      $('lod-slider').disabled = auto;
      if (auto) unforce();
      else if (selectedId !== null) forceModel(selectedId, Number($('lod-slider').value)).catch((e) => fail(String(e)));
    });
    $('lod-slider').addEventListener('input', () => {
      if (selectedId !== null && !$('lod-auto').checked)
        forceModel(selectedId, Number($('lod-slider').value)).catch((e) => fail(String(e)));
    });

    /// What a click at window position `pos` picks: the building and whether it
    /// is the forced model's (for scripts and tests).
    function pickAt(pos) {
      const picked = viewer.scene.pick(new Cesium.Cartesian2(pos.x, pos.y));
      if (!picked || typeof picked.getProperty !== 'function') return null;
      return { building_id: String(picked.getProperty('building_id')), forced: !!forcedModel && picked.primitive === forcedModel };
    }

    Object.assign(state, { selectBuilding, forceModel, unforce, flyToBuilding, screenPositionOf, loadIndex, pickAt });
    // Start far enough to see the whole scene with its coarse tiles.
    await viewer.zoomTo(tileset, new Cesium.HeadingPitchRange(0.3, -0.7, tileset.boundingSphere.radius * 2.5));
    await new Promise((resolve) => {
      if (tileset.tilesLoaded && state.allTilesLoadedCount > 0) resolve();
      else tileset.allTilesLoaded.addEventListener(() => resolve());
    });
    state.ready = true;
  }

  main().catch((e) => fail(String(e && e.stack ? e.stack : e)));
})();
