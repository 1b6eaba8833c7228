// The page of `lsys3d edit`: editor, viewer, controls, stats, export and save, over the API of docs/edit.md.
// Every edit asks for the tube soup (fast) and, a moment later, the union; each kind on its own channel, so a
// newer edit cancels the server's older work of that kind. A stale answer is never shown over a newer one.
import { createViewer } from './viewer.js';
import { createEditor } from './editor.js';

const token = new URLSearchParams(location.search).get('token');
const auth = token ? { 'X-Lsys3d-Token': token } : {};
const FULL_DELAY = 250; // ms of quiet after an edit before the union is asked for (the soup: at once)
const $ = (id) => document.getElementById(id);

const TURTLE_CONTROLS = ['step', 'width', 'width_scale', 'length_scale', 'elasticity', 'tropism', 'angle_jitter',
  'length_jitter', 'width_jitter', 'branch_roll', 'branch_drop'];
// slider ranges where the option's own range is open (the number box beside takes any value)
const RANGES = { angle_jitter: [0, 30], branch_roll: [0, 180], length_jitter: [0, 1], width_jitter: [0, 1],
  branch_drop: [0, 1], elasticity: [0, 1], tropism: [-1, 1] };
const OPTION_CONTROLS = ['sides', 'min_sides', 'leaf_size', 'leaf_size_variation', 'bark_color_variation'];

const state = {
  doc: null,
  version: null,
  iterations: null, // null: the grammar's own
  seed: null,
  options: {}, // flat names of GenerateOptions set by the controls
  turtle: {}, // [turtle] settings set by the controls
  specs: new Map(),
  seq: 0,
  shown: { seq: -1, kind: null },
  soupId: null,
  fullId: null,
  grammar: null,
  timings: [], // {kind, seq, ms}: from the keystroke to the tree on screen
  errors: 0,
};

async function call(path, body) {
  const init = body === undefined ? { headers: auth } : {
    method: 'POST', headers: { ...auth, 'Content-Type': 'application/json' }, body: JSON.stringify(body),
  };
  const response = await fetch(path, init);
  let json = null;
  try { json = await response.json(); } catch { json = null; }
  return { status: response.status, json };
}

async function bytes(path) {
  const response = await fetch(path, { headers: auth });
  if (!response.ok) throw new Error(`${path}: ${response.status}`);
  return response.arrayBuffer();
}

const viewer = createViewer($('viewer'));
// the page's timings start at the input event's own time stamp: the keypress, as near as a page can know it
const editor = createEditor($('editor'), { onChange: (text, stamp) => edited(stamp ?? performance.now()) });

function body(kind, extra = {}) {
  const options = { ...state.options };
  if (Object.keys(state.turtle).length) options.turtle = { ...state.turtle };
  if (kind !== 'full') options.union = false;
  if (kind === 'full' && $('lods').checked) options.lod = [0, 1, 2, 3];
  return {
    text: editor.value,
    suffix: state.doc.suffix,
    iterations: state.iterations,
    seed: state.seed,
    options,
    export: kind === 'soup' ? { skeleton_curves: true } : {},
    channel: kind,
    ...extra,
  };
}

let fullTimer = null;
function edited(t0) {
  state.seq += 1;
  const seq = state.seq;
  clearTimeout(fullTimer);
  // the union is asked for once the soup is on screen and the edits paused: it never takes the cores from
  // the soup of the same edit (a newer edit cancels it on the server anyway)
  grow('soup', seq, t0).finally(() => {
    if (seq !== state.seq || state.options.union === false) return;
    fullTimer = setTimeout(() => grow('full', seq, t0), Math.max(0, FULL_DELAY - (performance.now() - t0)));
  });
  flags();
}

async function grow(kind, seq, t0) {
  status(kind === 'soup' ? 'growing the tube soup…' : 'growing the union…');
  const { status: code, json } = await call('/api/generate', body(kind));
  if (seq < state.seq && kind === 'soup') return; // a newer edit is on its way
  if (code === 409) return; // superseded on the server
  if (code === 422 && json?.error) {
    if (seq === state.seq) {
      editor.setError(json.error);
      diagnostics(json.error.diagnostics || [], json.error);
      status('error');
    }
    return;
  }
  if (code !== 200) {
    status(`${kind}: ${json?.error?.message || `HTTP ${code}`}`);
    return;
  }
  if (seq < state.shown.seq || (seq === state.shown.seq && state.shown.kind === 'full')) return;
  const glb = await bytes(json.asset);
  const fetched = performance.now() - t0;
  if (seq < state.shown.seq || (seq === state.shown.seq && state.shown.kind === 'full')) return;
  await viewer.load(glb);
  await new Promise((resolve) => requestAnimationFrame(() => resolve())); // after the frame that draws it
  state.shown = { seq, kind };
  // ms: the input event to the frame drawn; fetched: to the .glb received; worker: the job in the worker
  state.timings.push({ kind, seq, ms: performance.now() - t0, fetched, worker: 1000 * json.stats.seconds.total });
  state[kind === 'full' ? 'fullId' : 'soupId'] = json.id;
  if (kind === 'soup' && seq === state.seq) state.fullId = null;
  if (seq === state.seq) {
    editor.setError(null);
    editor.setWarnings(json.diagnostics.map((d) => ({ message: d.message, symbols: warnedSymbols(d.message) })));
    diagnostics(json.diagnostics, null);
    grammarControls(json.grammar);
  }
  stats(json.stats, kind);
  status(kind === 'full' || state.options.union === false ? 'ready' : 'tube soup shown; union on its way…');
}

// the symbols a warning names, quoted after its colon: "...: symbols with no rule and no turtle meaning: 'X', 'Y'",
// "...: module parameters the turtle ignores: 'F' (w), '+' (a)"
function warnedSymbols(message) {
  const tail = message.slice(message.lastIndexOf(': ') + 2);
  return [...tail.matchAll(/'([^']+)'/g)].map((m) => m[1]);
}

function status(text) {
  $('status').textContent = text;
}

function diagnostics(list, error) {
  const box = $('diagnostics');
  box.innerHTML = '';
  if (error) {
    const p = document.createElement('div');
    p.className = 'error';
    p.textContent = `error: ${error.line ? `${error.line}:${error.col ?? ''}: ` : ''}${error.message}`;
    box.appendChild(p);
  }
  for (const d of list) {
    const p = document.createElement('div');
    p.className = 'warning';
    p.dataset.testid = 'warning';
    p.textContent = `warning: ${typeof d === 'string' ? d : d.message}`;
    box.appendChild(p);
  }
}

function stats(s, kind) {
  const rows = [
    ['modules', s.modules], ['segments', s.segments], ['tubes', s.tubes],
    ['bark triangles', s.triangles], ['bark vertices', s.vertices],
    ['leaves', s.leaves], ['leaf triangles', s.leaf_triangles],
    ['watertight', s.watertight === null ? '–' : s.watertight ? 'yes' : 'no'],
  ];
  const stages = Object.entries(s.seconds).filter(([k]) => k !== 'total');
  let html = '<tr><th>counts</th><th></th><th>seconds</th><th></th></tr>';
  const n = Math.max(rows.length, stages.length + 1);
  for (let i = 0; i < n; i++) {
    const [a, b] = rows[i] || ['', ''];
    const total = s.cached ? 'total (kept tree)' : 'total (worker)';
    const [c, d] = stages[i] || (i === stages.length ? [total, s.seconds.total] : ['', '']);
    const fmt = (v) => (typeof v === 'number' ? (Number.isInteger(v) ? v.toLocaleString('en') : v.toFixed(3)) : v);
    html += `<tr><td>${a}</td><td class="n">${fmt(b)}</td><td>${c}</td><td class="n">${fmt(d)}</td></tr>`;
  }
  $('stats').innerHTML = html;
  $('mesh-kind').textContent = kind === 'full' ? 'union (the asset)' : 'tube soup (preview)';
  $('mesh-kind').dataset.kind = kind;
}

// ------------------------------------------------------------------ controls
function control(host, { name, label, value, low, high, step, integer, help, onInput }) {
  const row = document.createElement('div');
  row.className = 'control';
  row.dataset.name = name;
  const l = document.createElement('label');
  l.textContent = label;
  l.title = help || name;
  const range = document.createElement('input');
  range.type = 'range';
  range.min = low;
  range.max = high;
  range.step = step;
  range.value = value;
  range.dataset.testid = `slider-${name}`;
  const number = document.createElement('input');
  number.type = 'number';
  number.step = step;
  number.value = value;
  const set = (v, from) => {
    if (from !== range) range.value = v;
    if (from !== number) number.value = v;
    row.classList.add('touched');
    onInput(integer ? Math.round(Number(v)) : Number(v));
  };
  range.oninput = () => set(range.value, range);
  number.onchange = () => set(number.value, number);
  row.append(l, range, number);
  host.appendChild(row);
  const update = (v) => { range.value = v; number.value = v; };
  row.__update = update;
  return { row, update };
}

function span(value, low, high) {
  const lo = low ?? Math.min(0, value * 2);
  let hi = high ?? Math.max(value * 2, lo + 1);
  if (hi > 1e6) hi = Math.max(value * 4, lo + 1);
  return [lo, hi, (hi - lo) / 200];
}

// the grammar's numeric defines and its angle are written into the text (TOML grammars), so Save keeps them
const NUMBER = '(-?[0-9][0-9_]*(?:\\.[0-9_]*)?(?:[eE][-+]?[0-9]+)?)';

// the body of the TOML table `scope`: [start, end) of `[scope]` up to the next header, or of `scope = {...}`
function tomlSection(text, scope) {
  const header = new RegExp(`^[ \\t]*\\[${scope}\\][^\\n]*\\n?`, 'm').exec(text);
  if (header) {
    const start = header.index + header[0].length;
    const next = /^[ \t]*\[/m.exec(text.slice(start));
    return { start, end: next ? start + next.index : text.length, inline: false };
  }
  const inline = new RegExp(`^[ \\t]*${scope}\\s*=\\s*\\{`, 'm').exec(text);
  if (inline) {
    const start = inline.index + inline[0].length;
    const close = text.indexOf('}', start);
    return { start, end: close < 0 ? text.length : close, inline: true };
  }
  return null;
}

// where the number (or, with `array`, the [x, y, z]) of `name` is written: in table `scope`, or at the top level
function tomlValue(text, name, scope, array = false) {
  const value = array ? '(\\[[^\\]\\n]*\\])' : NUMBER;
  let start = 0;
  let end = text.length;
  let re = new RegExp(`^()[ \\t]*${name}\\s*=\\s*${value}`, 'm');
  if (scope) {
    const section = tomlSection(text, scope);
    if (!section) return null;
    ({ start, end } = section);
    re = new RegExp(`(^|[\\s{,])${name}\\s*=\\s*${value}`);
  }
  const m = re.exec(text.slice(start, end));
  if (!m) return null;
  const at = start + m.index + m[0].length - m[2].length;
  return [at, at + m[2].length];
}

function tomlNumber(text, name, scope) {
  return tomlValue(text, name, scope);
}

// a [turtle] setting written into the text (TOML): replaced where it is, else added to the table (made if
// missing). False when the text cannot take it (a native dialect, an inline `turtle = {...}` without the key).
function writeTurtle(name, value) {
  if (state.doc.suffix !== '.toml') return false;
  const text = editor.value;
  const written = Array.isArray(value) ? `[${value.map((v) => Number(v.toFixed(6))).join(', ')}]` : String(Number(value.toFixed(6)));
  const at = tomlValue(text, name, 'turtle', Array.isArray(value));
  if (at) {
    editor.replace(at[0], at[1], written);
    return true;
  }
  const section = tomlSection(text, 'turtle');
  if (section?.inline) return false;
  if (section) editor.replace(section.start, section.start, `${name} = ${written}\n`);
  else editor.replace(text.length, text.length, `${text.endsWith('\n') ? '' : '\n'}\n[turtle]\n${name} = ${written}\n`);
  return true;
}

let grammarKey = '';
function grammarControls(g) {
  state.grammar = g;
  if (state.seed === null) $('seed-controls').querySelector('[data-name="seed"]')?.__update(g.seed);
  const host = $('grammar-controls');
  const key = JSON.stringify([Object.keys(g.defines), state.doc.suffix]);
  if (key === grammarKey) return;
  grammarKey = key;
  host.innerHTML = '';
  const toml = state.doc.suffix === '.toml';
  control(host, {
    name: 'iterations', label: 'iterations', value: state.iterations ?? g.iterations, low: 0,
    high: Math.max(10, g.iterations + 3), step: 1, integer: true, help: 'number of generations (-n)',
    onInput: (v) => { state.iterations = v; edited(performance.now()); },
  });
  const writers = [['angle', g.angle, null, 'the default rotation angle, degrees']];
  for (const [name, value] of Object.entries(g.defines)) writers.push([name, value, 'defines', 'a define of the grammar']);
  for (const [name, value, scope, help] of writers) {
    const [lo, hi, step] = name === 'angle' ? [0, 180, 0.05] : span(value);
    const c = control(host, {
      name: `define-${name}`, label: scope ? `${name} (define)` : name, value, low: lo, high: hi, step,
      help: toml ? `${help}: written into the text` : `${help} (only TOML grammars can be changed from here)`,
      onInput: (v) => {
        const at = tomlNumber(editor.value, name, scope);
        if (!at) return;
        editor.replace(at[0], at[1], String(Number(v.toFixed(6))));
        edited(performance.now());
      },
    });
    if (!toml || !tomlNumber(editor.value, name, scope)) c.row.querySelectorAll('input').forEach((i) => (i.disabled = true));
  }
  // the turtle's settings in force, for the controls not touched yet
  for (const [name, value] of Object.entries(g.turtle)) {
    if (name in state.turtle) continue;
    const rows = Array.isArray(value) ? ['x', 'y', 'z'].map((axis) => `${name} ${axis}`) : [name];
    rows.forEach((label, i) => {
      const row = $('option-controls').querySelector(`[data-name="${label}"]`);
      row?.__update?.(Array.isArray(value) ? value[i] : value);
    });
  }
}

function seedControls() {
  const host = $('seed-controls');
  control(host, {
    name: 'seed', label: 'seed', value: 0, low: 0, high: 200, step: 1, integer: true,
    help: 'seed of the stochastic rules and the jitters (--seed)',
    onInput: (v) => { state.seed = v; edited(performance.now()); },
  });
  const button = document.createElement('button');
  button.textContent = 'Seed variants';
  button.dataset.testid = 'variants-button';
  button.title = 'tube soups of the next five seeds; click one to use its seed';
  button.onclick = variants;
  $('variants').appendChild(button);
}

let variantViewer = null;
async function variants() {
  const strip = $('variants');
  strip.querySelectorAll('figure').forEach((f) => f.remove());
  if (!variantViewer) {
    const box = document.createElement('div');
    box.style.cssText = 'position:fixed;left:-1000px;top:0;width:240px;height:240px';
    document.body.appendChild(box);
    variantViewer = createViewer(box, { toolbar: false });
  }
  const first = (state.seed ?? state.grammar?.seed ?? 0) + 1;
  for (let i = 0; i < 5; i++) {
    const seed = first + i;
    const { status: code, json } = await call('/api/generate', body('soup', { seed, channel: 'variants', export: {} }));
    if (code !== 200) return;
    await variantViewer.load(await bytes(json.asset), { frame: true });
    const figure = document.createElement('figure');
    figure.dataset.testid = 'variant';
    const img = document.createElement('img');
    img.src = variantViewer.picture(168, 168);
    figure.append(img, `seed ${seed}`);
    figure.onclick = () => {
      state.seed = seed;
      $('seed-controls').querySelector('[data-name="seed"]').__update(seed);
      edited(performance.now());
    };
    strip.appendChild(figure);
  }
}

async function optionControls() {
  const { json } = await call('/api/options');
  for (const spec of json.options) state.specs.set(`${spec.group}:${spec.name}`, spec);
  const host = $('option-controls');
  const add = (target, spec, label, index) => {
    const value = index === undefined ? spec.default : spec.default[index];
    const fixed = RANGES[spec.name];
    const [lo, hi, step] = fixed ? [fixed[0], fixed[1], (fixed[1] - fixed[0]) / 200] : spec.kind === 'int' ? [spec.low ?? 0, spec.high ?? Math.max(value * 4, 16), 1]
      : span(value, spec.low ?? (spec.kind === 'vector' ? -1 : 0), spec.high ?? (spec.kind === 'vector' ? 1 : null));
    const c = control(target, {
      name: label, label, value, low: lo, high: hi, step, integer: spec.kind === 'int', help: spec.help,
      onInput: (v) => {
        if (spec.group === 'turtle') {
          let value = v;
          if (index !== undefined) {
            value = [...(state.turtle[spec.name] ?? state.grammar?.turtle?.[spec.name] ?? spec.default)];
            value[index] = v;
          }
          // into the grammar's [turtle] table when it can be (Save keeps it), else an override of it
          if (writeTurtle(spec.name, value)) delete state.turtle[spec.name];
          else state.turtle[spec.name] = value;
          if (index !== undefined && state.grammar) state.grammar.turtle[spec.name] = value;
        } else state.options[spec.name] = v;
        edited(performance.now());
      },
    });
    return c;
  };
  for (const name of TURTLE_CONTROLS) {
    const spec = state.specs.get(`turtle:${name}`);
    if (!spec) continue;
    if (spec.kind === 'vector') ['x', 'y', 'z'].forEach((axis, i) => add(host, spec, `${name} ${axis}`, i));
    else add(host, spec, name);
  }
  for (const name of OPTION_CONTROLS) {
    const spec = state.specs.get(`option:${name}`);
    if (spec) add(host, spec, name);
  }
  const all = $('all-options');
  for (const spec of json.options) {
    if (spec.group !== 'option' || OPTION_CONTROLS.includes(spec.name) || spec.name.startsWith('max_')) continue;
    if (spec.kind === 'bool') {
      const row = document.createElement('div');
      row.className = 'control';
      const box = document.createElement('input');
      box.type = 'checkbox';
      box.checked = spec.default;
      box.dataset.testid = `option-${spec.name}`;
      box.onchange = () => { state.options[spec.name] = box.checked; edited(performance.now()); };
      const l = document.createElement('label');
      l.textContent = spec.name;
      l.title = spec.help;
      row.append(l, box);
      all.appendChild(row);
    } else add(all, spec, spec.name);
  }
}

function flags() {
  const parts = [];
  if (state.iterations !== null) parts.push(`-n ${state.iterations}`);
  if (state.seed !== null) parts.push(`--seed ${state.seed}`);
  for (const [k, v] of Object.entries(state.options)) {
    const flag = `--${k.replace(/_/g, '-')}`;
    parts.push(typeof v === 'boolean' ? (v ? flag : `--no-${k.replace(/_/g, '-')}`) : `${flag} ${v}`);
  }
  for (const [k, v] of Object.entries(state.turtle)) parts.push(`--turtle ${k}=${Array.isArray(v) ? `[${v}]` : v}`);
  $('flags').textContent = parts.length ? `lsys3d generate ${state.doc.name} ${parts.join(' ')}` : '';
}

// ------------------------------------------------------------------ save and export
async function save() {
  const out = $('save-status');
  out.className = '';
  out.textContent = 'saving…';
  const { status: code, json } = await call('/api/save', { text: editor.value, version: state.version });
  if (code === 200) {
    state.version = json.version;
    out.textContent = `saved ${new Date().toLocaleTimeString()}`;
    out.dataset.saved = String(Number(out.dataset.saved || 0) + 1);
  } else {
    out.className = 'error';
    out.textContent = json?.error?.message || `HTTP ${code}`;
  }
}

async function download(format) {
  const id = state.fullId || state.soupId;
  if (!id) return;
  status(`writing ${format}…`);
  const response = await fetch(`/api/asset/${id}${format}`, { headers: auth });
  if (!response.ok) {
    status(`${format}: ${(await response.json())?.error?.message || response.status}`);
    return;
  }
  const url = URL.createObjectURL(await response.blob());
  const a = document.createElement('a');
  a.href = url;
  a.download = `${state.doc.name.replace(/\.[^.]*$/, '')}${format}`;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
  status('ready');
}

// ------------------------------------------------------------------ compiling on a first run
async function watchCompiling() {
  for (;;) {
    const { json } = await call('/api/status');
    if (json?.compiling) {
      status(`compiling lsys3d's kernels (first run only): ${json.compiling.done} of up to ${json.compiling.total}…`);
    } else if (json && json.ready > 0) return;
    else status('starting the workers…');
    await new Promise((r) => setTimeout(r, 700));
  }
}

async function main() {
  const { json: doc } = await call('/api/document');
  state.doc = doc;
  state.version = doc.version;
  editor.suffix = doc.suffix;
  editor.value = doc.text;
  $('file').textContent = doc.path ? doc.path : `${doc.name} (bundled preset, read-only)`;
  $('save').disabled = doc.read_only;
  $('save').onclick = save;
  document.addEventListener('keydown', (e) => {
    if ((e.ctrlKey || e.metaKey) && e.key === 's') {
      e.preventDefault();
      if (!doc.read_only) save();
    }
  });
  for (const b of document.querySelectorAll('#exports button')) b.onclick = () => download(b.dataset.format);
  $('lods').onchange = () => edited(performance.now());
  seedControls();
  await optionControls();
  watchCompiling();
  edited(performance.now());
}

window.lsys3d = { viewer, editor, state };
main();
