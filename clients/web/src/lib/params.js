// The page's address: which page it is and the deep-link parameters.
// `params` is a URLSearchParams.

// The page an address's query names: the player (?reenactment=ID), the
// live preview (?job=JOBID), else the library. {page, id}.
export function routeOf(params) {
  const reenactment = params.get('reenactment');
  if (reenactment) return { page: 'player', id: reenactment };
  const job = params.get('job');
  if (job) return { page: 'live', id: job };
  return { page: 'library', id: '' };
}

// &bg=RRGGBB (with or without '#') as '#rrggbb', else `fallback`.
export function backgroundFromParams(params, fallback) {
  const bg = (params.get('bg') || '').replace(/^#/, '');
  return /^[0-9a-fA-F]{6}$/.test(bg) ? `#${bg}` : fallback;
}

// A finite number parameter, else null (absent or not a number).
export function numberParam(params, name) {
  if (!params.has(name)) return null;
  const x = Number(params.get(name));
  return Number.isFinite(x) ? x : null;
}

// The view options every 3D page reads: &controls=0 (the view alone),
// &mirror=1, &floor=0.
export function viewParams(params) {
  return {
    controls: params.get('controls') !== '0',
    mirror: params.get('mirror') === '1',
    floor: params.get('floor') !== '0',
  };
}

// The player's deep link (&t &yaw &speed &a &b &paused &appearance),
// numbers as given (null when absent): the player clamps them.
export function playerParams(params) {
  return {
    ...viewParams(params),
    t: numberParam(params, 't'),
    yaw: numberParam(params, 'yaw'),
    speed: numberParam(params, 'speed'),
    a: numberParam(params, 'a'),
    b: numberParam(params, 'b'),
    paused: params.get('paused') === '1',
    appearance: params.get('appearance') !== '0',
  };
}
