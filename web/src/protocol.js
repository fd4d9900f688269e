// The studio's protocol, page side (docs/studio.md, "Messages" and "Frames"): one WebSocket to
// /TOKEN/ws beside the page, JSON messages both ways and binary frame messages from the server.

export const PROTOCOL = 1;

// fm_cache_attr (include/flockmorph/cache.h) → how the page views its bytes.
export const ATTR = { TET_VERTICES: 1, POSITION: 2, VELOCITY: 3, ID: 5, PHASE: 6, GROUP: 7 };
const VIEWS = { 1: Float32Array, 2: Float32Array, 3: Float32Array, 5: Uint32Array, 6: Uint8Array, 7: Uint8Array };

// A binary frame message: its header and a typed-array view per attribute, in place (the server
// aligns each array to 16 bytes), no per-agent JavaScript objects.
export function parseFrame(buffer) {
  const dv = new DataView(buffer);
  const magic = String.fromCharCode(dv.getUint8(0), dv.getUint8(1), dv.getUint8(2), dv.getUint8(3));
  if (magic !== 'FMF1') throw new Error(`not a frame message (${magic})`);
  const frame = { generation: dv.getUint32(4, true), k: dv.getUint32(8, true), agents: dv.getUint32(12, true),
    attrs: {}, buffer };
  const count = dv.getUint32(16, true);
  for (let i = 0; i < count; i++) {
    const at = 20 + 12 * i;
    const attr = dv.getUint32(at, true), offset = dv.getUint32(at + 4, true), bytes = dv.getUint32(at + 8, true);
    const View = VIEWS[attr];
    if (View) frame.attrs[attr] = new View(buffer, offset, bytes / View.BYTES_PER_ELEMENT);
  }
  return frame;
}

export class Connection extends EventTarget {
  constructor() {
    super();
    const base = location.pathname.replace(/[^/]*$/, '');
    this.url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}${base}ws`;
    this.open();
  }

  open() {
    this.ws = new WebSocket(this.url);
    this.ws.binaryType = 'arraybuffer';
    this.ws.onopen = () => this.send({ type: 'hello', protocol: PROTOCOL });
    this.ws.onmessage = (e) => this.receive(e.data);
    this.ws.onclose = () => this.dispatchEvent(new CustomEvent('closed'));
  }

  receive(data) {
    if (data instanceof ArrayBuffer) {
      this.dispatchEvent(new CustomEvent('frame', { detail: parseFrame(data) }));
      return;
    }
    const m = JSON.parse(data);
    if (m.type === 'hello' && m.protocol !== PROTOCOL) {
      this.dispatchEvent(new CustomEvent('error', { detail: { message: `the server speaks protocol ${m.protocol}, this page ${PROTOCOL}: reload` } }));
    }
    this.dispatchEvent(new CustomEvent(m.type, { detail: m }));
  }

  send(message) {
    if (this.ws.readyState === WebSocket.OPEN) this.ws.send(JSON.stringify(message));
  }
}
