// File drops on an element: the `drop-hover` highlight while files are dragged over it, and the
// dropped files handed on. Used by the page's drop zones (app.js) and the tracking panel.

/** True when a drag event carries files. */
export function hasFiles(e) {
  return [...(e.dataTransfer?.types || [])].includes('Files');
}

/**
 * Makes `el` a drop zone: while files are dragged over it, it has the class `drop-hover`;
 * dropped files that `accept(files)` takes go to `onDrop(files)`, and the drop stops at `el`
 * (the page-wide drop handler does not see it). Files it does not accept go on to the page.
 * `isolate`: dragover events stop at `el` as well.
 */
export function dropZone(el, onDrop, { accept = () => true, isolate = false } = {}) {
  el.addEventListener('dragover', (e) => {
    if (!hasFiles(e)) return;
    e.preventDefault();
    if (isolate) e.stopPropagation();
    e.dataTransfer.dropEffect = 'copy';
    el.classList.add('drop-hover');
  });
  el.addEventListener('dragleave', (e) => {
    if (!el.contains(e.relatedTarget)) el.classList.remove('drop-hover');
  });
  el.addEventListener('drop', (e) => {
    el.classList.remove('drop-hover');
    document.body.classList.remove('dragging');
    const files = [...(e.dataTransfer?.files || [])];
    if (!files.length || !accept(files)) return;
    e.preventDefault();
    e.stopPropagation();
    onDrop(files);
  });
}
