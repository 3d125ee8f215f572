// Which avatar each side of a call starts with (www/js/call.js): the two sides start as
// different people. The first side in a room takes the first default avatar (the bundled
// default targets, then the library), the second (who joins a room the other is in, or answers
// a pasted offer) the next one; and if the other side's avatar is the same all the same (they
// chose it), the second side takes the first default that is not theirs, as soon as the other
// side's status says so. A side whose avatar was chosen (the address's `avatar=`, the menu, the
// experimenter, a schedule) keeps it; the sides are decided once a call, so a reload or a server
// restart that brings the room back changes nobody.

/** Fills the model menu `sel` with `keys` of `models` (bundled, then Your models) and selects `value`. */
export function fillModelMenu(sel, models, keys, value) {
  sel.replaceChildren();
  const groups = [['Bundled', keys.filter((k) => k.startsWith('b:'))], ['Your models', keys.filter((k) => k.startsWith('s:'))]];
  for (const [label, list] of groups) {
    if (!list.length) continue;
    const g = document.createElement('optgroup');
    g.label = label;
    for (const k of list) g.append(new Option(models.get(k).name, k));
    sel.append(g);
  }
  sel.value = value;
}

/** The bundled avatars (model keys "b:FILE") in the order the sides take them by default. */
export function defaultAvatars(call) {
  const m = call.manifest;
  const files = [...new Set([...(m.targets || []), ...(m.library || [])])].filter((f) => f !== m.source);
  return files.map((f) => `b:${f}`).filter((k) => call.models.has(k));
}

/**
 * `call`: the page's state (`manifest`, `models`, `avatar`, `avatarChosen`, `second`);
 * `pick(key)`: makes a default avatar this side's (not a choice).
 */
export class AvatarSides {
  constructor(call, pick) {
    this.call = call;
    this.pick = pick;
  }

  /** This side is the second (true) or the first (false) of its call: the default follows. */
  take(second) {
    const c = this.call;
    if (c.second !== null) return;
    c.second = second;
    const next = defaultAvatars(c)[1];
    if (second && !c.avatarChosen && next) this.pick(next);
  }

  /** The other side's avatar is `name`: the second side, on a default, moves off it. */
  avoid(name) {
    const c = this.call;
    if (!c.second || c.avatarChosen || !name || c.avatar?.target?.name !== name) return;
    const key = defaultAvatars(c).find((k) => c.models.get(k).name !== name);
    if (key) this.pick(key);
  }

  /** The call ended: the next one decides again. */
  reset() {
    this.call.second = null;
  }
}
