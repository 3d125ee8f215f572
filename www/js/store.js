// Keeping models in the browser: every model made (enrolled) or dropped in the page is stored in
// IndexedDB, on this machine only (nothing is uploaded anywhere), and listed in the "Your models"
// panel, where it can be renamed, used as the source, added as a target, downloaded or deleted.
//
// Records: { id, name, bytes: ArrayBuffer (the .fmm file), origin: "built" | "dropped" | "photo", created,
// size, fingerprint, hash }. A record is written in one transaction with the complete, validated
// file, so a half-made model is never stored (a cancelled or failed build writes nothing). Each
// record is checked once per page load (the first listing) from its header, length and checksum
// (the package's modelSummary: no model is built): a damaged one is listed as damaged with the
// reason (and can be deleted); the others load as usual, and what
// the list shows of them is kept by the file's hash, so keeping a model the page has already
// parsed (its `info` given) parses nothing again. The .fmm reader keeps reading older format
// versions, so stored models stay loadable by later versions of the page.

const DB_NAME = 'facemimic';
const DB_VERSION = 1;
const STORE = 'models';

function req(r) {
  return new Promise((resolve, reject) => {
    r.onsuccess = () => resolve(r.result);
    r.onerror = () => reject(r.error);
  });
}

function done(tx) {
  return new Promise((resolve, reject) => {
    tx.oncomplete = () => resolve();
    tx.onabort = () => reject(tx.error || new Error('transaction aborted'));
    tx.onerror = () => reject(tx.error);
  });
}

/** FNV-1a over the whole file: finds a model that is already stored. */
export function hashBytes(bytes) {
  let h = 2166136261;
  for (let i = 0; i < bytes.length; i++) h = Math.imul(h ^ bytes[i], 16777619) >>> 0;
  return `${bytes.length}:${h.toString(16)}`;
}

/** The IndexedDB model store (no UI). */
export class ModelStore {
  constructor(db) {
    this.db = db;
  }

  static async open(name = DB_NAME) {
    if (typeof indexedDB === 'undefined') throw new Error('this browser has no IndexedDB');
    const open = indexedDB.open(name, DB_VERSION);
    open.onupgradeneeded = () => {
      const db = open.result;
      if (!db.objectStoreNames.contains(STORE)) db.createObjectStore(STORE, { keyPath: 'id', autoIncrement: true });
    };
    return new ModelStore(await req(open));
  }

  /** Every record, oldest first. */
  async list() {
    const tx = this.db.transaction(STORE, 'readonly');
    const all = await req(tx.objectStore(STORE).getAll());
    return all.sort((a, b) => (a.created || 0) - (b.created || 0) || a.id - b.id);
  }

  /** Stores a complete model file; returns its id (an existing one if the same file is stored). */
  async add({ name, bytes, origin, fingerprint = '' }) {
    const copy = new Uint8Array(bytes).slice().buffer; // detached from any wasm memory
    const hash = hashBytes(new Uint8Array(copy));
    const same = (await this.list()).find((r) => r.hash === hash);
    if (same) return { id: same.id, existed: true, hash };
    const tx = this.db.transaction(STORE, 'readwrite');
    const record = { name, bytes: copy, origin, created: Date.now(), size: copy.byteLength, fingerprint, hash };
    const id = await req(tx.objectStore(STORE).add(record));
    await done(tx);
    return { id, existed: false, hash };
  }

  async get(id) {
    return req(this.db.transaction(STORE, 'readonly').objectStore(STORE).get(id));
  }

  async rename(id, name) {
    const tx = this.db.transaction(STORE, 'readwrite');
    const s = tx.objectStore(STORE);
    const r = await req(s.get(id));
    if (!r) throw new Error('no such model');
    r.name = name;
    s.put(r);
    await done(tx);
  }

  async remove(id) {
    const tx = this.db.transaction(STORE, 'readwrite');
    tx.objectStore(STORE).delete(id);
    await done(tx);
  }
}

/**
 * The "Your models" panel. `page` is the page's hooks: { fm, notify, useAsSource(bytes, name),
 * addAsTarget(bytes, name), inspect(model, name) }.
 */
export class ModelShelf {
  constructor(host, page) {
    this.host = host;
    this.page = page;
    this.store = null;
    this.items = []; // { record, info | null, error | null }
    this.summaries = new Map(); // file hash -> what the list shows of a valid model (see summary)
    this.ready = this.init();
    window.facemimicModels = this; // for the console and the end-to-end tests
  }

  async init() {
    this.host.replaceChildren(this.el('p', 'hint', 'Opening the model store…'));
    try {
      this.store = await ModelStore.open();
    } catch (e) {
      this.host.replaceChildren(this.el('p', 'hint', `Models cannot be kept in this browser (${e.message || e}); they still work until the page is closed.`));
      document.body.dataset.shelf = 'unavailable';
      return;
    }
    await this.refresh();
    document.body.dataset.shelf = 'ready';
  }

  el(tag, cls, text) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined) e.textContent = text;
    return e;
  }

  /** Validates every stored record and redraws the list; damaged records are reported. */
  async refresh() {
    if (!this.store) return;
    let records;
    try {
      records = await this.store.list();
    } catch (e) {
      this.page.notify('error', 'Could not read the stored models', e.message || String(e));
      return;
    }
    const items = [];
    const damaged = [];
    for (const record of records) {
      let info = (record.hash && this.summaries.get(record.hash)) || null;
      let error = null;
      try {
        if (!info) info = this.validate(record);
      } catch (e) {
        error = e.message || String(e);
        damaged.push(`${record.name || `#${record.id}`}: ${error}`);
      }
      items.push({ record, info, error });
    }
    const reported = new Set(this.items.filter((i) => i.error).map((i) => i.record.id));
    const fresh = items.filter((i) => i.error && !reported.has(i.record.id));
    if (fresh.length) {
      this.page.notify('error', `${fresh.length} stored model(s) could not be read`, fresh.map((i) => `${i.record.name || `#${i.record.id}`}: ${i.error}`).join('; '));
    }
    this.items = items;
    this.render();
  }

  /**
   * A stored record's model file, checked from its header, length and checksum (the package's
   * `modelSummary`, which builds no model): its summary (throws why not). The full read happens
   * when the model is used.
   */
  validate(record) {
    if (!(record.bytes instanceof ArrayBuffer)) throw new Error('the stored entry holds no model file');
    const info = summary(this.page.fm.modelSummary(new Uint8Array(record.bytes)));
    if (record.hash) this.summaries.set(record.hash, info);
    return info;
  }

  /**
   * Keeps a model file. `info`: the `Model.info()` of these very bytes when the caller has parsed
   * them already (a dropped, built or photo model); without it the file is parsed to validate it.
   * Returns the record id, or null if it was refused.
   */
  async keep(bytes, name, origin, { quiet = false, info = null } = {}) {
    await this.ready;
    if (!this.store) return null;
    if (!info) {
      try {
        const m = this.page.fm.Model.fromBytes(bytes);
        info = m.info();
        m.free();
      } catch (e) {
        if (!quiet) this.page.notify('error', `Not kept: ${name}`, e.message || String(e));
        return null;
      }
    }
    try {
      const { id, existed, hash } = await this.store.add({ name, bytes, origin, fingerprint: info.fingerprint });
      this.summaries.set(hash, summary(info));
      await this.refresh();
      if (!existed && origin === 'built') this.page.notify('info', `Kept ${name}`, 'in this browser; find it under Your models');
      return id;
    } catch (e) {
      this.page.notify('error', `Could not keep ${name}`, e.message || String(e));
      return null;
    }
  }

  render() {
    const list = this.el('ul', 'shelf');
    list.setAttribute('aria-label', 'Models kept in this browser');
    if (!this.items.length) {
      this.host.replaceChildren(this.el('p', 'hint', 'Models you create or drop here are kept in this browser (never uploaded) and listed here.'));
      return;
    }
    for (const item of this.items) list.append(this.row(item));
    this.host.replaceChildren(list);
  }

  row({ record, info, error }) {
    const li = this.el('li', error ? 'shelf-item damaged' : 'shelf-item');
    li.dataset.id = String(record.id);
    const name = this.el('span', 'shelf-name', record.name || `#${record.id}`);
    const meta = error
      ? this.el('small', 'shelf-meta', `damaged: ${error}`)
      : this.el(
          'small',
          'shelf-meta',
          info.isPhoto
            ? `photo target · ${(record.size / 1e6).toFixed(2)} MB`
            : `${record.origin === 'built' ? 'created here' : 'dropped'} · ${info.shapeModes}+${info.appearanceModes} modes · ${(record.size / 1e6).toFixed(1)} MB`,
        );
    const text = this.el('div', 'shelf-text');
    text.append(name, meta);
    const buttons = this.el('div', 'shelf-buttons');
    const button = (label, title, fn) => {
      const b = this.el('button', 'btn small', label);
      b.type = 'button';
      b.title = title;
      b.addEventListener('click', () => fn().catch((e) => this.page.notify('error', `${label}: ${record.name}`, e.message || String(e))));
      buttons.append(b);
      return b;
    };
    const bytes = () => new Uint8Array(record.bytes);
    if (!error) {
      // A photo target has no modes to drive others with: it is a target only.
      if (!info.isPhoto) button('Source', 'Use as the source face', async () => this.page.useAsSource(bytes(), record.name));
      button('Target', 'Add as a target face', async () => this.page.addAsTarget(bytes(), record.name));
      button('Save', 'Download the .fmm file', async () => download(bytes(), `${safeName(record.name)}.fmm`));
      button('Rename', 'Rename this model', async () => {
        const next = prompt('New name', record.name);
        if (next === null || !next.trim()) return;
        await this.store.rename(record.id, next.trim().slice(0, 80));
        await this.refresh();
      });
    }
    button('Delete', 'Delete it from this browser', async () => {
      if (!confirm(`Delete ${record.name} from this browser?`)) return;
      await this.store.remove(record.id);
      await this.refresh();
    });
    li.append(text, buttons);
    return li;
  }
}

/** What the list shows of a model (from its `Model.info()` or `modelSummary()`: both have these). */
function summary(info) {
  const { isPhoto, shapeModes, appearanceModes, fingerprint } = info;
  return { isPhoto, shapeModes, appearanceModes, fingerprint };
}

export function safeName(name) {
  return (name || 'model').replace(/[^\w.-]+/g, '_').slice(0, 60) || 'model';
}

export function download(bytes, fileName) {
  const url = URL.createObjectURL(new Blob([bytes], { type: 'application/octet-stream' }));
  const a = document.createElement('a');
  a.href = url;
  a.download = fileName;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}
