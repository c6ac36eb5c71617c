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

export class FleetMap {
  constructor(elementId, config, onSelect) {
    this.map = baseMap(elementId, config);
    this.markers = new Map();
    this.onSelect = onSelect;
    this.fitted = false;
  }

  update(vehicles) {
    const seen = new Set();
    for (const v of vehicles) {
      if (v.lat === null || v.lon === null) continue;
      seen.add(v.id);
      const style = { radius: 8, weight: 2, color: '#212529', fillColor: COLOURS[v.state] || '#868e96',
        fillOpacity: 0.95, className: `bike bike-${v.state}` };
      let m = this.markers.get(v.id);
      if (!m) {
        m = L.circleMarker([v.lat, v.lon], style).addTo(this.map);
        m.on('click', () => this.onSelect(v.id));
        this.markers.set(v.id, m);
      } else {
        m.setLatLng([v.lat, v.lon]);
        m.setStyle(style);
      }
      // className is set once at creation by Leaflet: keep the state on the element for CSS/tests.
      const path = m.getElement();
      if (path) {
        path.setAttribute('data-vehicle', v.id);
        path.setAttribute('data-state', v.state);
      }
      m.bindTooltip(tooltip(v));
    }
    for (const [id, m] of this.markers) {
      if (!seen.has(id)) { m.remove(); this.markers.delete(id); }
    }
    if (!this.fitted) this.fit();
  }

  fit() {
    const points = [...this.markers.values()].map((m) => m.getLatLng());
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
  }

  show(v) {
    this.layer.clearLayers();
    const points = [];
    for (const ride of v.rides) {
      const track = ride.track.filter((p) => p[0] !== null && p[1] !== null);
      if (track.length > 1) {
        L.polyline(track, { color: '#1971c2', weight: 3, opacity: 0.8 }).addTo(this.layer);
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
}
