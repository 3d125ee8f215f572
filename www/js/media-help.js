// What the page says about a video the browser cannot play (a format it has no decoder for: HEVC,
// ProRes, a damaged or mislabelled file...): in plain words, with what to do about it, the
// commands that convert it to what every browser plays (H.264 in MP4, or VP9 in WebM), each
// with a Copy button, and the browser's own words kept small for whoever needs them.

/** A file name as one word of a shell command (quoted when it needs to be). */
export function shellWord(name) {
  if (/^[\w.,+@%=:/-]+$/.test(name)) return name;
  return `"${name.replace(/(["\\$`])/g, '\\$1')}"`;
}

/**
 * The commands that convert the video `name` (ffmpeg): `[{ label, command }]`, H.264 MP4 first,
 * then WebM; the output is named after the input (never the input itself). Sound is dropped
 * (`-an`): the page uses the picture only.
 */
export function convertCommands(name) {
  const file = String(name || 'input.mov').split(/[/\\]/).pop();
  const base = file.replace(/\.[^.]*$/, '') || 'video';
  const out = (ext) => (`${base}.${ext}`.toLowerCase() === file.toLowerCase() ? `${base}-converted.${ext}` : `${base}.${ext}`);
  const q = shellWord;
  return [
    { label: 'H.264 MP4', command: `ffmpeg -i ${q(file)} -c:v libx264 -pix_fmt yuv420p -an ${q(out('mp4'))}` },
    { label: 'WebM', command: `ffmpeg -i ${q(file)} -c:v libvpx-vp9 -crf 32 -b:v 0 -an ${q(out('webm'))}` },
  ];
}

function el(tag, className, text) {
  const e = document.createElement(tag);
  if (className) e.className = className;
  if (text !== undefined) e.textContent = text;
  return e;
}

/** Copies `text` to the clipboard (or, where the browser refuses, selects `node`'s text for Ctrl+C). */
async function copy(text, node) {
  try {
    await navigator.clipboard.writeText(text);
    return true;
  } catch {
    const range = document.createRange();
    range.selectNodeContents(node);
    const sel = getSelection();
    sel.removeAllRanges();
    sel.addRange(range);
    return document.execCommand?.('copy') ?? false;
  }
}

/** One command in a box of its own, with its Copy button. */
function commandRow({ label, command }) {
  const row = el('div', 'media-cmd');
  // Lines break between an option and the next, never inside one ("-pix_fmt yuv420p" stays whole).
  const code = el('code');
  const units = (command.match(/"(?:[^"\\]|\\.)*"|\S+/g) || []).reduce((out, w) => {
    if (out.length && out[out.length - 1].startsWith('-') && !out[out.length - 1].includes(' ') && !w.startsWith('-')) out[out.length - 1] += ` ${w}`;
    else out.push(w);
    return out;
  }, []);
  units.forEach((u, i) => code.append(...(i ? [' '] : []), u.length <= 32 ? el('span', '', u) : u)); // a long name may break
  const btn = el('button', 'btn media-copy', 'Copy');
  btn.type = 'button';
  btn.setAttribute('aria-label', `Copy the command that converts it to ${label}`);
  btn.addEventListener('click', async () => {
    const ok = await copy(command, code);
    btn.textContent = ok ? 'Copied' : 'Selected';
    setTimeout(() => (btn.textContent = 'Copy'), 1600);
  });
  row.append(el('span', 'media-cmd-label', label), code, btn);
  return row;
}

/**
 * The help for a video the browser cannot play, as an element (`.media-help`): `name` the file,
 * `detail` the browser's own words (or ''), `still` what goes on meanwhile (a sentence, or '').
 */
export function unplayableHelp({ name, detail = '', still = '' }) {
  const box = el('div', 'media-help');
  box.append(
    el('p', '', 'This browser cannot play the format of this video (its codec or container). Convert it to an H.264 MP4 or a WebM, then drop the converted file:'),
    ...convertCommands(name).map(commandRow),
  );
  const tail = el('p', 'media-note');
  tail.append('ffmpeg is free: ', Object.assign(el('a', '', 'ffmpeg.org'), { href: 'https://ffmpeg.org/download.html', target: '_blank', rel: 'noopener' }), '.');
  if (still) tail.append(` ${still}`);
  box.append(tail);
  if (detail) {
    const d = el('details', 'media-detail');
    d.append(el('summary', '', "The browser's words"), el('code', '', detail));
    box.append(d);
  }
  return box;
}

/** The line a tracking panel shows for such a video. */
export function unplayableLine(name) {
  return `${name}: this browser cannot play its format. Convert it to an H.264 MP4 or a WebM (the commands are in the notice), then drop it again.`;
}
