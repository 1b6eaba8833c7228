// The grammar editor: a plain <textarea> with a highlighted copy of its text drawn underneath, a gutter of
// line numbers, and the CLI's diagnostics inline (the error on its line and column). Written small instead of
// a vendored editor library: CodeMirror 6 needs a bundler, and a textarea keeps the browser's own editing,
// undo, selection and accessibility.

let warned = new Map(); // symbol -> the warning naming it (underlined in rules, the message as its tooltip)
const esc = (s) => s.replace(/&/g, '&amp;').replace(/</g, '&lt;').replace(/>/g, '&gt;');
const span = (cls, s) => `<span class="t-${cls}">${esc(s)}</span>`;

// the L-system inside rules: arrows, branches, turtle symbols, modules and their parameters. Outside parentheses
// a module is one character (lsys3d's TOML) or a word (the native dialects); inside, names are parameters.
const RULE = [
  [/^(->|→|-->|<|>|:)/, 'arrow'],
  [/^[[\]]/, 'branch'],
  [/^[0-9]+(\.[0-9]*)?([eE][-+]?[0-9]+)?/, 'number'],
  [/^[+\-&^\\/|!~$"'%@]/, 'turtle'],
];

function rule(text, words = false) {
  let out = '';
  let depth = 0;
  while (text) {
    let m;
    if (text[0] === '(' || text[0] === ')') {
      depth = Math.max(0, depth + (text[0] === '(' ? 1 : -1));
      out += span('paren', text[0]);
      text = text.slice(1);
      continue;
    }
    if (depth > 0) {
      m = /^[A-Za-z_][A-Za-z0-9_]*|^[0-9.]+([eE][-+]?[0-9]+)?|^[^()A-Za-z0-9_.]+/.exec(text);
      const cls = /^[A-Za-z_]/.test(m[0]) ? 'param' : /^[0-9.]/.test(m[0]) ? 'number' : 'paren';
      out += span(cls, m[0]);
      text = text.slice(m[0].length);
      continue;
    }
    if ((m = (words ? /^[A-Za-z_][A-Za-z0-9_]*/ : /^[A-Za-z]/).exec(text))) {
      const warning = warned.get(m[0]);
      out += warning
        ? `<span class="t-symbol warned" data-testid="warned-symbol" title="${esc(warning)}">${esc(m[0])}</span>`
        : span('symbol', m[0]);
      text = text.slice(m[0].length);
      continue;
    }
    let hit = false;
    for (const [re, cls] of RULE) {
      if ((m = re.exec(text))) {
        const warning = cls === 'turtle' && warned.get(m[0]);
        out += warning
          ? `<span class="t-${cls} warned" data-testid="warned-symbol" title="${esc(warning)}">${esc(m[0])}</span>`
          : span(cls, m[0]);
        text = text.slice(m[0].length);
        hit = true;
        break;
      }
    }
    if (!hit) {
      out += esc(text[0]);
      text = text.slice(1);
    }
  }
  return out;
}

// TOML, line by line, carrying multi-line strings ("""...""" and '''...''') across lines
function tomlLine(line, state) {
  let out = '';
  let rest = line;
  if (state.multi) {
    const end = rest.indexOf(state.multi);
    if (end < 0) return rule(rest);
    out += rule(rest.slice(0, end)) + span('string', state.multi);
    rest = rest.slice(end + 3);
    state.multi = null;
  }
  const header = /^(\s*)(\[\[?[^\]]*\]\]?)/.exec(rest);
  if (header && !out) {
    out += esc(header[1]) + span('table', header[2]);
    rest = rest.slice(header[0].length);
  }
  const key = /^(\s*)([A-Za-z0-9_\-."]+)(\s*=)/.exec(rest);
  if (key && !out) {
    out += esc(key[1]) + span('key', key[2]) + esc(key[3]);
    rest = rest.slice(key[0].length);
  }
  while (rest) {
    let m;
    if ((m = /^("""|''')/.exec(rest))) {
      const close = rest.indexOf(m[1], 3);
      if (close < 0) {
        out += span('string', m[1]) + rule(rest.slice(3));
        state.multi = m[1];
        return out;
      }
      out += span('string', m[1]) + rule(rest.slice(3, close)) + span('string', m[1]);
      rest = rest.slice(close + 3);
    } else if ((m = /^"((?:[^"\\]|\\.)*)("?)/.exec(rest)) || (m = /^'([^']*)('?)/.exec(rest))) {
      const q = rest[0];
      out += span('string', q) + rule(m[1]) + (m[2] ? span('string', q) : '');
      rest = rest.slice(m[0].length);
    } else if ((m = /^#.*/.exec(rest))) {
      out += span('comment', m[0]);
      rest = '';
    } else if ((m = /^(true|false)\b/.exec(rest))) {
      out += span('number', m[0]);
      rest = rest.slice(m[0].length);
    } else if ((m = /^[-+]?[0-9][0-9_]*(\.[0-9_]*)?([eE][-+]?[0-9]+)?/.exec(rest))) {
      out += span('number', m[0]);
      rest = rest.slice(m[0].length);
    } else if ((m = /^([A-Za-z_][A-Za-z0-9_\-]*)(\s*=)/.exec(rest))) {
      out += span('key', m[1]) + esc(m[2]);
      rest = rest.slice(m[0].length);
    } else {
      out += esc(rest[0]);
      rest = rest.slice(1);
    }
  }
  return out;
}

// the native dialects: L-Py (.lpy), cpfg (.l), Lparser (.ls)
const NATIVE_KEYWORDS =
  /^(Axiom|axiom|production|productions|derivation length|homomorphism|decomposition|interpretation|endlsystem|endgrammar|group|endgroup|define|ignore|consider|maximum depth|module|nproduce|produce|Start|End|StartEach|EndEach|def|return|if|else|elif|for|in|import|from|extern|lsystem|recursion|angle|thickness|seed)\b/;

function nativeLine(line, state, suffix) {
  let out = '';
  let rest = line;
  if (state.comment) {
    const end = rest.indexOf('*/');
    if (end < 0) return span('comment', rest);
    out += span('comment', rest.slice(0, end + 2));
    rest = rest.slice(end + 2);
    state.comment = false;
  }
  const lineComment = suffix === '.l' ? /^\/\/.*/ : /^#.*/;
  while (rest) {
    let m;
    if (suffix === '.l' && rest.startsWith('/*')) {
      const end = rest.indexOf('*/', 2);
      if (end < 0) {
        state.comment = true;
        return out + span('comment', rest);
      }
      out += span('comment', rest.slice(0, end + 2));
      rest = rest.slice(end + 2);
    } else if ((m = lineComment.exec(rest))) {
      out += span('comment', m[0]);
      rest = '';
    } else if ((m = NATIVE_KEYWORDS.exec(rest)) && (!out || /[\s:;(]$/.test(out.replace(/<[^>]*>/g, '')))) {
      out += span('key', m[0]);
      rest = rest.slice(m[0].length);
    } else if ((m = /^"[^"]*"?|^'[^']*'?/.exec(rest))) {
      out += span('string', m[0]);
      rest = rest.slice(m[0].length);
    } else {
      // up to the next comment or string: L-system text
      const stop = rest.search(suffix === '.l' ? /\/\/|\/\*|"/ : /#|"/);
      const piece = stop <= 0 ? rest : rest.slice(0, stop);
      out += rule(piece, true);
      rest = stop <= 0 ? '' : rest.slice(stop);
    }
  }
  return out;
}

export function highlight(text, suffix) {
  const state = { multi: null, comment: false };
  return text.split('\n').map((line) => (suffix === '.toml' ? tomlLine(line, state) : nativeLine(line, state, suffix)));
}

export function createEditor(host, { onChange, suffix = '.toml' } = {}) {
  host.classList.add('grammar-editor');
  host.innerHTML = `<pre class="gutter" aria-hidden="true"></pre><div class="code"><pre class="highlight" aria-hidden="true"></pre><textarea spellcheck="false" autocapitalize="off" autocomplete="off" data-testid="editor" aria-label="grammar"></textarea><div class="marks"></div></div>`;
  const gutter = host.querySelector('.gutter');
  const code = host.querySelector('.code');
  const pre = host.querySelector('.highlight');
  const area = host.querySelector('textarea');
  const marks = host.querySelector('.marks');
  let diagnostics = { error: null, warnings: [] };

  function lineHeight() {
    return parseFloat(getComputedStyle(area).lineHeight) || 18;
  }

  function draw() {
    warned = new Map();
    for (const w of diagnostics.warnings) for (const symbol of w.symbols) warned.set(symbol, w.message);
    const lines = highlight(area.value, suffix);
    const error = diagnostics.error;
    if (error && error.line && error.line <= lines.length) {
      lines[error.line - 1] = `<span class="error-line">${lines[error.line - 1] || ' '}</span>`;
    }
    pre.innerHTML = lines.join('\n') + '\n';
    gutter.textContent = lines.map((_, i) => String(i + 1)).join('\n') + '\n';
    if ((error && error.line) || warned.size) {
      gutter.innerHTML = lines
        .map((html, i) => {
          if (error && i + 1 === error.line) return `<span class="error-gutter" title="error">${i + 1}</span>`;
          if (html.includes('class="t-symbol warned"') || html.includes('class="t-turtle warned"')) {
            return `<span class="warning-gutter" title="warning">${i + 1}</span>`;
          }
          return `${i + 1}`;
        })
        .join('\n');
    }
    marks.innerHTML = '';
    if (error) {
      const box = document.createElement('div');
      box.className = 'inline-error';
      box.dataset.testid = 'inline-error';
      box.dataset.line = error.line ?? '';
      box.dataset.col = error.col ?? '';
      const where = error.line ? `${error.line}:${error.col ?? ''}` : '';
      box.textContent = `${where ? where + ' ' : ''}${error.message}`;
      const top = error.line ? error.line * lineHeight() + 4 : 4;
      box.style.top = `${top - area.scrollTop}px`;
      if (error.line && error.col) {
        const caret = document.createElement('div');
        caret.className = 'error-caret';
        const ch = measureChar();
        caret.style.left = `${8 + (error.col - 1) * ch - area.scrollLeft}px`;
        caret.style.top = `${(error.line - 1) * lineHeight() + 4 - area.scrollTop}px`;
        caret.style.height = `${lineHeight()}px`;
        caret.style.width = `${ch}px`;
        marks.appendChild(caret);
      }
      marks.appendChild(box);
    }
    sync();
  }

  let charWidth = 0;
  function measureChar() {
    if (!charWidth) {
      const probe = document.createElement('span');
      probe.textContent = 'M'.repeat(100);
      probe.style.cssText = 'position:absolute;visibility:hidden;white-space:pre';
      pre.appendChild(probe);
      charWidth = probe.getBoundingClientRect().width / 100 || 7.8;
      probe.remove();
    }
    return charWidth;
  }

  function sync() {
    pre.scrollTop = area.scrollTop;
    pre.scrollLeft = area.scrollLeft;
    gutter.scrollTop = area.scrollTop;
  }

  area.addEventListener('input', (e) => {
    onChange?.(area.value, e.timeStamp); // the request first, then the highlighting
    draw();
  });
  area.addEventListener('scroll', () => {
    sync();
    if (diagnostics.error) draw();
  });
  area.addEventListener('keydown', (e) => {
    if (e.key === 'Tab' && !e.ctrlKey && !e.metaKey) {
      e.preventDefault();
      document.execCommand('insertText', false, '    ');
    }
  });

  return {
    area,
    get value() {
      return area.value;
    },
    set value(text) {
      area.value = text;
      draw();
    },
    set suffix(s) {
      suffix = s;
      draw();
    },
    setError(error) {
      diagnostics = { ...diagnostics, error };
      draw();
    },
    /** Warnings to mark in the text: [{message, symbols: [...]}] (the symbols the CLI's warning names). */
    setWarnings(warnings) {
      diagnostics = { ...diagnostics, warnings };
      draw();
    },
    /** Replace the characters [start, end) (a slider writing a define's value), keeping the caret. */
    replace(start, end, text) {
      const { selectionStart, selectionEnd } = area;
      area.setRangeText(text, start, end, 'preserve');
      if (document.activeElement !== area) area.setSelectionRange(selectionStart, selectionEnd);
      draw();
    },
  };
}
