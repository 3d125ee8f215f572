// The face cards on the stage: the source's and each target's (a canvas, a caption with the
// name, the replace and remove buttons), a target's look (its picture's aspect, the photo note,
// the backdrop notice), and the placeholder card while a photo's face is looked for. What a
// card's buttons, drops and clicks do is given by the caller (targets.js).

import { dropZone } from './drop.js';
import { isMediaFile } from './tracking.js';
import { POPOUT_ICON } from './output-controls.js';
import { app, $, notVideos, FACE_ASPECT, PICTURE_ASPECT, PHOTO_NOTE, PHOTO_TITLE } from './page-state.js';

/** A small button showing the SVG path `d`, its action in `data-action`. */
function iconButton(action, title, d) {
  const b = document.createElement('button');
  b.type = 'button';
  b.className = 'icon-btn';
  b.dataset.action = action;
  b.title = title;
  b.innerHTML = `<svg viewBox="0 0 16 16" aria-hidden="true"><path d="${d}"/></svg>`;
  return b;
}

/**
 * A face card: a canvas, a caption with the name, and buttons. role: "source" | "target".
 * `actions`: `pick(slot)` (choose files for the card's slot), `load(files, slot)` (files dropped
 * on it), `remove(entry)` (its remove button), `popout(entry)` (its output view's button),
 * `inspect(entry, role)` (a click on the face).
 */
export function makeCard(role, actions) {
  const el = document.createElement('figure');
  el.className = `card face-card ${role}`;
  const canvas = document.createElement('canvas');
  canvas.className = 'face';
  const cap = document.createElement('figcaption');
  const name = document.createElement('span');
  name.className = 'name';
  const tools = document.createElement('span');
  tools.className = 'tools';
  const replace = iconButton('replace', 'Replace with a model file…', 'M3 8a5 5 0 0 1 8.5-3.5M13 8a5 5 0 0 1-8.5 3.5M11.5 1.5v3h-3M4.5 14.5v-3h3');
  tools.append(replace);
  if (role === 'target') {
    tools.prepend(iconButton('popout', 'Pop out: this avatar alone in a window of its own, for OBS, Zoom, Meet or Discord (Output view)', POPOUT_ICON));
    tools.append(iconButton('remove', 'Remove this target', 'M4 4l8 8M12 4l-8 8'));
  }
  cap.append(name, tools);
  el.append(canvas, cap);
  if (role === 'source') {
    const badge = document.createElement('span');
    badge.className = 'badge';
    badge.textContent = 'source';
    el.append(badge);
  }
  app.hidpi.watch(canvas);

  const slot = () => (role === 'source' ? { kind: 'source' } : { kind: 'replace', entry: entryOf(el) });
  replace.addEventListener('click', () => actions.pick(slot()));
  tools.querySelector('[data-action="remove"]')?.addEventListener('click', () => actions.remove(entryOf(el)));
  tools.querySelector('[data-action="popout"]')?.addEventListener('click', () => actions.popout(entryOf(el)));
  // A video or a photo dropped on the source goes on to the page, which tracks it (the source is
  // driven by it); on a target, a photo replaces the target with a photo target (and a video
  // goes on to the page).
  dropZone(el, (files) => actions.load(files, slot()), { accept: role === 'source' ? (files) => !files.every(isMediaFile) : notVideos });
  // Clicking a face shows its model in the inspector.
  canvas.addEventListener('click', () => {
    const entry = role === 'source' ? app.source : entryOf(el);
    if (!entry) return;
    actions.inspect(entry, role);
  });
  return { el, canvas };
}

/** The target whose card is `cardEl`. */
function entryOf(cardEl) {
  return app.targets.find((t) => t.card === cardEl);
}

/** A card's name, tooltips and labels from its entry. */
export function setCardName(entry) {
  const name = entry.card.querySelector('.name');
  name.textContent = entry.name;
  name.title = entry.file;
  const canvas = entry.canvas;
  const role = entry === app.source ? 'Source' : 'Target';
  canvas.setAttribute('role', 'img');
  canvas.setAttribute('aria-label', `${role} face: ${entry.name}`);
  entry.card.querySelector('[data-action="replace"]').setAttribute('aria-label', `Replace ${entry.name} with a model file`);
  entry.card.querySelector('[data-action="remove"]')?.setAttribute('aria-label', `Remove target ${entry.name}`);
  entry.card.querySelector('[data-action="popout"]')?.setAttribute('aria-label', `Pop out ${entry.name} (output view)`);
  entry.card.dataset.model = entry.name;
}

/** Whether a target is drawn composited into its picture (its canvas then has the picture's aspect). */
function composited(entry) {
  return !app.settings.faceOnly && !!entry.info.backdrop;
}

/** A target card's look: its canvas's aspect (the picture's, or a face's), the photo note, the
 *  backdrop notice. */
export function styleTarget(entry) {
  const card = entry.card;
  const b = entry.info.backdrop;
  const ar = composited(entry) ? Math.min(PICTURE_ASPECT[1], Math.max(PICTURE_ASPECT[0], b.width / b.height)) : FACE_ASPECT;
  card.style.setProperty('--ar', ar.toFixed(4));
  card.classList.toggle('picture', composited(entry));
  card.classList.toggle('photo', !!entry.info.isPhoto);
  let badge = card.querySelector('.badge');
  if (entry.info.isPhoto) {
    if (!badge) {
      badge = document.createElement('span');
      badge.className = 'badge';
      card.append(badge);
    }
    badge.textContent = PHOTO_NOTE;
    badge.title = PHOTO_TITLE;
  } else badge?.remove();
  const name = card.querySelector('.name');
  const notes = [entry.file];
  if (entry.info.isPhoto) notes.push(PHOTO_TITLE);
  if (entry.info.backdropNotice) notes.push(`Shown face only: ${entry.info.backdropNotice}`);
  name.title = notes.join('\n');
  const what = entry.info.isPhoto ? `Target (${PHOTO_NOTE})` : 'Target';
  entry.canvas.setAttribute('aria-label', `${what}: ${entry.name}${composited(entry) ? ', in its picture' : ''}`);
}


/** A placeholder card while a photo's face is looked for. */
export function pendingCard(fileName) {
  const el = document.createElement('figure');
  el.className = 'card face-card pending';
  el.setAttribute('aria-busy', 'true');
  const box = document.createElement('div');
  box.className = 'pending-box';
  box.textContent = 'Finding the face…';
  const cap = document.createElement('figcaption');
  const name = document.createElement('span');
  name.className = 'name';
  name.textContent = fileName;
  cap.append(name);
  el.append(box, cap);
  $('faces').insertBefore(el, $('add-card'));
  return el;
}
