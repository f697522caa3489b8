(() => {
  'use strict';
  const labels = (typeof HZ !== 'undefined' && HZ.labels) || { truth: 'truth', lead: 'technique' };
  const zooms = (window.HZ && HZ.zooms) || [0, 1, 2, 4, 8];
  const views = Array.from(document.querySelectorAll('.view'));
  const zoomButtons = Array.from(document.querySelectorAll('[data-zoom]'));
  let zoom = 0;  // 0: fit the panel; n: n screen pixels per image pixel
  let syncing = false;  // set while views are moved by the script, not the reader

  // ---------------------------------------------------------------- zoom
  const firstImage = (view) => view.querySelector('img');
  const contentOf = (view) => view.querySelector('.content');

  function layout(view) {
    const content = contentOf(view);
    const img = firstImage(view);
    if (!content || !img) return;
    const nw = Number(img.dataset.width) || img.naturalWidth;   // a preview's full width
    content.style.width = zoom > 0 && nw > 0 ? (nw * zoom) + 'px' : '';
    view.classList.toggle('zoomed', zoom > 0);
    // nearest-neighbour whenever an image pixel covers at least a screen pixel
    const shown = content.getBoundingClientRect().width;
    view.classList.toggle('pixelated', nw > 0 && shown >= nw - 0.5);
  }

  function centre(view) {
    const w = view.scrollWidth, h = view.scrollHeight;
    return [w ? (view.scrollLeft + view.clientWidth / 2) / w : 0.5,
            h ? (view.scrollTop + view.clientHeight / 2) / h : 0.5];
  }

  function onScreen(view) {
    const r = view.getBoundingClientRect();
    return r.bottom > 0 && r.top < window.innerHeight && r.width > 0;
  }

  function setZoom(z) {
    if (!zooms.includes(z)) return;
    const ref = views.find(onScreen) || views[0];
    const [fx, fy] = ref && zoom > 0 ? centre(ref) : [0.5, 0.5];
    zoom = z;
    syncing = true;
    views.forEach(layout);
    views.forEach((v) => {
      v.scrollLeft = fx * v.scrollWidth - v.clientWidth / 2;
      v.scrollTop = fy * v.scrollHeight - v.clientHeight / 2;
    });
    syncing = false;
    views.forEach(sharpen);
    zoomButtons.forEach((b) => b.setAttribute('aria-pressed', String(Number(b.dataset.zoom) === z)));
    document.body.dataset.zoom = String(z);
  }

  // ------------------------------- previews: full resolution on demand
  // An image larger than the report shows at "fit" comes as a downsampled preview (src) and its
  // full-resolution file (data-full; its width in data-width, which the zoom scales by): a view
  // loads the full files once the reader zooms in while it is on screen.
  const fullOf = new Map();
  document.querySelectorAll('img[data-full]').forEach((img) => fullOf.set(img.getAttribute('src'), img.dataset.full));
  function sharpen(view) {
    if (zoom === 0 || !fullOf.size || !onScreen(view)) return;
    view.querySelectorAll('img').forEach((img) => {
      const full = fullOf.get(img.getAttribute('src'));
      if (full) img.setAttribute('src', full);
    });
  }
  window.addEventListener('scroll', () => { if (zoom > 0) views.forEach(sharpen); }, { passive: true });

  zoomButtons.forEach((b) => b.addEventListener('click', () => setZoom(Number(b.dataset.zoom))));
  views.forEach((v) => v.querySelectorAll('img').forEach((img) => {
    if (!img.complete) img.addEventListener('load', () => layout(v), { once: true });
  }));
  window.addEventListener('load', () => views.forEach(layout));
  window.addEventListener('resize', () => views.forEach(layout));
  views.forEach(layout);

  document.addEventListener('keydown', (e) => {
    if (e.ctrlKey || e.metaKey || e.altKey) return;
    const t = e.target;
    if (t && (t.tagName === 'INPUT' || t.tagName === 'TEXTAREA' || t.isContentEditable)) return;
    const z = e.key === 'f' ? 0 : Number(e.key);
    if (e.key !== ' ' && Number.isInteger(z) && zooms.includes(z)) { setZoom(z); e.preventDefault(); }
  });

  // ------------------------------------------------- pan: all views follow
  function follow(src) {
    if (syncing || zoom === 0) return;
    const mx = src.scrollWidth - src.clientWidth, my = src.scrollHeight - src.clientHeight;
    const fx = mx > 0 ? src.scrollLeft / mx : 0, fy = my > 0 ? src.scrollTop / my : 0;
    syncing = true;
    for (const v of views) {
      if (v === src) continue;
      const x = fx * (v.scrollWidth - v.clientWidth), y = fy * (v.scrollHeight - v.clientHeight);
      if (Math.abs(v.scrollLeft - x) > 1) v.scrollLeft = x;
      if (Math.abs(v.scrollTop - y) > 1) v.scrollTop = y;
    }
    syncing = false;
  }

  views.forEach((v) => {
    let drag = null;
    v.addEventListener('scroll', () => { if (!syncing && v.dataset.active === '1') follow(v); }, { passive: true });
    v.addEventListener('pointerenter', () => { views.forEach((w) => { w.dataset.active = w === v ? '1' : ''; }); });
    v.addEventListener('wheel', () => { views.forEach((w) => { w.dataset.active = w === v ? '1' : ''; }); }, { passive: true });
    v.addEventListener('pointerdown', (e) => {
      if (e.button !== 0) return;
      views.forEach((w) => { w.dataset.active = w === v ? '1' : ''; });
      drag = { x: e.clientX, y: e.clientY, sl: v.scrollLeft, st: v.scrollTop, moved: false, id: e.pointerId,
               split: v.classList.contains('swipe-view') && zoom === 0 };
      if (drag.split) { setSplitFromPointer(v, e); e.preventDefault(); }
    });
    v.addEventListener('pointermove', (e) => {
      if (!drag) return;
      const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
      if (!drag.moved && Math.hypot(dx, dy) > 3) {
        drag.moved = true;
        try { v.setPointerCapture(drag.id); } catch (err) { /* pointer already gone */ }
        v.classList.add('dragging');
      }
      if (drag.split) setSplitFromPointer(v, e);
      else if (drag.moved && zoom > 0) { v.scrollLeft = drag.sl - dx; v.scrollTop = drag.st - dy; follow(v); }
    });
    const end = () => {
      if (drag && drag.moved) v.dataset.dragged = '1';
      drag = null;
      v.classList.remove('dragging');
    };
    v.addEventListener('pointerup', end);
    v.addEventListener('pointercancel', end);
  });

  // ----------------------------------------------------------- swipe
  function setSplit(fig, pct) {
    const p = Math.max(0, Math.min(100, pct));
    const over = fig.querySelector('img.over'), split = fig.querySelector('.split');
    const range = fig.querySelector('.swipe-range');
    if (over) over.style.clipPath = 'inset(0 ' + (100 - p) + '% 0 0)';
    if (split) split.style.left = p + '%';
    if (range && Number(range.value) !== p) range.value = String(p);
  }
  function setSplitFromPointer(view, e) {
    const stack = view.querySelector('.stack');
    if (!stack) return;
    const r = stack.getBoundingClientRect();
    if (r.width > 0) setSplit(view.closest('.swipe'), 100 * (e.clientX - r.left) / r.width);
  }
  document.querySelectorAll('.swipe').forEach((fig) => {
    const range = fig.querySelector('.swipe-range');
    if (!range) return;
    range.addEventListener('input', () => setSplit(fig, Number(range.value)));
    setSplit(fig, Number(range.value));
  });

  // ------------------------------------------------------------ flip
  const hoverFlip = document.getElementById('hover-flip');
  document.querySelectorAll('.flip').forEach((fig) => {
    const view = fig.querySelector('.view');
    const img = fig.querySelector('img.flip-img');
    const tag = fig.querySelector('.which');
    if (!view || !img || !tag) return;
    const own = fig.dataset.own;
    const other = own === 'truth' ? 'lead' : 'truth';
    const src = { truth: img.dataset.truth, lead: img.dataset.lead };
    const azimuth = (img.alt.split(', ').pop()) || '';
    function show(side) {
      if (fig.dataset.showing === side) return;
      img.setAttribute('src', src[side]);
      sharpen(view);
      img.alt = labels[side] + ', ' + azimuth;
      tag.textContent = labels[side];
      tag.className = 'tag tl which tag-' + side;
      fig.dataset.showing = side;
      fig.classList.toggle('flipped', side !== own);
    }
    const toggle = () => show(fig.dataset.showing === own ? other : own);
    view.addEventListener('pointerenter', (e) => {
      if (e.pointerType === 'mouse' && (!hoverFlip || hoverFlip.checked)) show(other);
    });
    view.addEventListener('pointerleave', (e) => { if (e.pointerType === 'mouse') show(own); });
    view.addEventListener('click', () => {
      if (view.dataset.dragged) { delete view.dataset.dragged; return; }
      toggle();
    });
    view.addEventListener('keydown', (e) => {
      if (e.key === 'Enter' || e.key === ' ') { toggle(); e.preventDefault(); }
    });
    view.addEventListener('blur', () => show(own));
  });

  // ------------------------------------------------------------ copy
  const copy = document.getElementById('copy');
  const code = document.getElementById('command');
  if (copy && code) {
    copy.addEventListener('click', () => {
      const done = (ok) => {
        copy.textContent = ok ? 'copied' : 'selected: press Ctrl+C';
        setTimeout(() => { copy.textContent = 'copy'; }, 1600);
      };
      const select = () => {
        const range = document.createRange();
        range.selectNodeContents(code);
        const sel = window.getSelection();
        sel.removeAllRanges();
        sel.addRange(range);
        let ok = false;
        try { ok = document.execCommand('copy'); } catch (err) { ok = false; }
        done(ok);
      };
      if (navigator.clipboard && window.isSecureContext) {
        navigator.clipboard.writeText(code.textContent).then(() => done(true), select);
      } else {
        select();
      }
    });
  }
})();
