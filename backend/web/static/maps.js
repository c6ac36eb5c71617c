// The fleet map and the vehicle page's map, over Leaflet (Debian's libjs-leaflet, global L).
// Without a tile URL the map has no tiles: a plain background, the bikes and tracks still drawn.
// Tooltips are DOM nodes built with textContent: Leaflet would parse a string as HTML.
import { el } from './dom.js';

export const STATES = {
  parked: 'Parked', riding: 'Riding', alarm: 'Alarm', low_battery: 'Low battery',
  offline: 'Offline', unknown: 'Unknown',
};
const COLOURS = {
  parked: '#2b8a3e', riding: '#1971c2', alarm: '#e03131', low_battery: '#f08c00',
  offline: '#868e96', unknown: '#868e96',
};

function baseMap(elementId, config) {
  const map = L.map(elementId, { attributionControl: false, zoomSnap: 0.25 });
  if (config && config.tile_url) {
    L.tileLayer(config.tile_url, { maxZoom: 19 }).addTo(map);
    if (config.tile_attribution) {
      // Our own credit line (textContent), not Leaflet's attribution control (innerHTML).
      map.getContainer().append(el('div', { className: 'tile-credit' }, config.tile_attribution));
    }
  }
  map.setView([0, 0], 2);
  return map;
}

function tooltip(v) {
  const soc = v.soc_pct === null ? '' : ` · ${v.soc_pct} %`;
  return el('span', {}, el('strong', {}, v.id), el('br'), `${STATES[v.state] || v.state}${soc}`);
}

// Up to this many bikes each marker is an SVG element (data-vehicle/data-state on it, which the
// tests and CSS use); above it one canvas draws them all: 10,000 SVG paths and their event
// handlers are what made the first load of a big fleet slow.
export const SVG_MARKER_LIMIT = 1000;

export class FleetMap {
  constructor(elementId, config, onSelect) {
    this.map = baseMap(elementId, config);
    this.markers = new Map(); // id -> {marker, v}
    this.onSelect = onSelect;
    this.fitted = false;
    this.canvas = null; // L.canvas renderer, made when the fleet outgrows SVG_MARKER_LIMIT
  }

  update(vehicles) {
    const placed = vehicles.filter((v) => v.lat !== null && v.lon !== null);
    const useCanvas = placed.length > SVG_MARKER_LIMIT;
    if (useCanvas && !this.canvas) {
      // Switching renderer: start over (the SVG markers cannot move onto a canvas).
      for (const { marker } of this.markers.values()) marker.remove();
      this.markers.clear();
      this.canvas = L.canvas({ padding: 0.5 });
    }
    const seen = new Set();
    for (const v of placed) {
      seen.add(v.id);
      const style = { radius: 8, weight: 2, color: '#212529', fillColor: COLOURS[v.state] || '#868e96',
        fillOpacity: 0.95, className: `bike bike-${v.state}` };
      if (this.canvas) style.renderer = this.canvas;
      const known = this.markers.get(v.id);
      if (!known) {
        const m = L.circleMarker([v.lat, v.lon], style);
        const entry = { marker: m, v };
        m.on('click', () => this.onSelect(entry.v.id));
        // Built when first shown, from the vehicle as it is then (not 10,000 DOM nodes up front).
        m.bindTooltip(() => tooltip(entry.v));
        m.addTo(this.map);
        this.markers.set(v.id, entry);
      } else {
        const old = known.v;
        known.v = v;
        if (old.lat !== v.lat || old.lon !== v.lon) known.marker.setLatLng([v.lat, v.lon]);
        if (old.state !== v.state) known.marker.setStyle(style);
      }
      // className is set once at creation by Leaflet: keep the state on the element for CSS/tests.
      const path = this.canvas ? null : this.markers.get(v.id).marker.getElement();
      if (path) {
        path.setAttribute('data-vehicle', v.id);
        path.setAttribute('data-state', v.state);
      }
    }
    for (const [id, { marker }] of this.markers) {
      if (!seen.has(id)) { marker.remove(); this.markers.delete(id); }
    }
    if (!this.fitted) this.fit();
    this.markDrawn(seen.size);
  }

  // #map's data-drawn: how many bikes the map has drawn, set once the canvas has painted them
  // (Leaflet's canvas redraws in the next animation frame; this runs after it).
  markDrawn(n) {
    const box = this.map.getContainer();
    requestAnimationFrame(() => { box.dataset.drawn = String(n); });
  }

  fit() {
    const points = [...this.markers.values()].map(({ marker }) => marker.getLatLng());
    // A hidden map has no size to fit into: fitted when it is first shown (resize()).
    if (points.length === 0 || this.map.getContainer().offsetWidth === 0) return;
    this.fitted = true;
    this.map.fitBounds(L.latLngBounds(points), { padding: [40, 40], maxZoom: 16 });
  }

  resize() {
    this.map.invalidateSize();
    if (!this.fitted) this.fit();
  }
}

export class VehicleMap {
  constructor(elementId, config) {
    this.map = baseMap(elementId, config);
    this.layer = L.layerGroup().addTo(this.map);
    this.rideLayer = L.layerGroup().addTo(this.map);
  }

  show(v) {
    this.layer.clearLayers();
    this.rideLayer.clearLayers();
    const points = [];
    for (const ride of v.rides) {
      const track = ride.track.filter((p) => p[0] !== null && p[1] !== null);
      if (track.length > 1) {
        L.polyline(track, { color: '#1971c2', weight: 3, opacity: 0.8, className: 'ride-track' })
          .addTo(this.layer);
        points.push(...track);
      }
    }
    if (v.lat !== null && v.lon !== null) {
      L.circleMarker([v.lat, v.lon], { radius: 9, color: '#212529', weight: 2,
        fillColor: COLOURS[v.state] || '#868e96', fillOpacity: 0.95, className: 'bike' })
        .bindTooltip(tooltip(v)).addTo(this.layer);
      points.push([v.lat, v.lon]);
    }
    this.map.invalidateSize();
    if (points.length === 1) this.map.setView(points[0], 16);
    else if (points.length > 1) this.map.fitBounds(L.latLngBounds(points), { padding: [20, 20] });
  }

  // One ride's full track (from its samples), drawn over the others and zoomed to; returns how
  // many points were drawn. The track's element carries data-ride and data-points (tests).
  showRide(rideId, points) {
    this.rideLayer.clearLayers();
    const track = points.filter((p) => p[0] !== null && p[1] !== null);
    if (track.length === 0) return 0;
    const line = L.polyline(track, { color: '#e8590c', weight: 5, opacity: 0.95,
      className: 'ride-selected' }).addTo(this.rideLayer);
    L.circleMarker(track[0], { radius: 6, color: '#2b8a3e', fillOpacity: 1, className: 'ride-start' })
      .addTo(this.rideLayer);
    L.circleMarker(track[track.length - 1], { radius: 6, color: '#c92a2a', fillOpacity: 1,
      className: 'ride-end' }).addTo(this.rideLayer);
    const path = line.getElement();
    if (path) {
      path.setAttribute('data-ride', rideId);
      path.setAttribute('data-points', String(track.length));
    }
    this.map.invalidateSize();
    if (track.length === 1) this.map.setView(track[0], 16);
    else this.map.fitBounds(L.latLngBounds(track), { padding: [20, 20] });
    return track.length;
  }
}
