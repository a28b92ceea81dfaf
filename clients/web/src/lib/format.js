// Words and figures as the app shows them: seconds, dates, titles of
// reenactments, the readouts of the player and the live preview.

// Seconds with two decimals; '–' for no number.
export function formatSeconds(s) {
  if (!Number.isFinite(s)) return '–';
  return s.toFixed(2);
}

// A date and time from Unix nanoseconds in the browser's locale; '' for
// none.
export function formatDate(unixNs) {
  const ms = Number(unixNs) / 1e6;
  if (!Number.isFinite(ms) || ms <= 0) return '';
  return new Date(ms).toLocaleString(undefined, {
    year: 'numeric',
    month: 'short',
    day: 'numeric',
    hour: '2-digit',
    minute: '2-digit',
  });
}

// A method's name as a person reads it: body -> Body, rigid-cylinders ->
// Rigid cylinders.
export function methodLabel(method) {
  const words = String(method || '')
    .replace(/[-_]+/g, ' ')
    .trim();
  return words ? words[0].toUpperCase() + words.slice(1) : 'Reenactment';
}

const FILE_EXTENSION = /\.[A-Za-z][A-Za-z0-9]{1,4}$/;

// A take named after the file it was uploaded from (ak.mcap,
// /data/2024-05-03_squat.mkv): the file name, else ''.
export function uploadedFileName(takeName) {
  const name = String(takeName || '').trim();
  return FILE_EXTENSION.test(name) ? name : '';
}

// What a reenactment is called (its library card, the player's title):
// the method and the take (its name without a file's folder and extension;
// the take id when it has no name).
export function cardTitle(r) {
  let take = String(r.take_name || '').trim();
  if (uploadedFileName(take)) {
    take = take
      .replace(/^.*[\\/]/, '')
      .replace(FILE_EXTENSION, '')
      .replace(/[_]+/g, ' ')
      .trim();
  }
  if (!take) take = r.take_id ? `take ${r.take_id}` : r.id;
  return `${methodLabel(r.method)} · ${take}`;
}

// The player's subtitle: method, length and frames.
export function reenactmentSummary(r, lengthS) {
  return `${r.method} · ${formatSeconds(lengthS)} s · ${r.frames} frames`;
}

// A turn in whole degrees: '-45°'.
export function formatDegrees(deg) {
  return `${Math.round(deg)}°`;
}

// The player's time readout: '1.25 / 3.00 s'.
export function timeReadout(time, length) {
  return `${formatSeconds(time)} / ${formatSeconds(length)} s`;
}

// The player's frame readout, counting from 1: 'frame 3 / 90'.
export function frameReadout(frame, frames) {
  return `frame ${frame + 1} / ${frames}`;
}

// The A-B loop's readout: '' without one, 'Loop 1.00–… s' while half set.
export function loopReadout(a, b) {
  if (a === null && b === null) return '';
  return `Loop ${a === null ? '…' : formatSeconds(a)}–${b === null ? '…' : formatSeconds(b)} s`;
}

// A job's state and stage: 'running · fitting' (`separator` between).
export function jobState(job, separator = ' · ') {
  return `${job.state}${job.stage ? `${separator}${job.stage}` : ''}`;
}

// The server's line in the library head: name, version, TLS, tokens.
export function serverLine(info) {
  return `${info.name} ${info.version}${info.tls ? ' · TLS' : ''}${info.auth ? ' · tokens' : ''}`;
}

// A live job's line in the library: method, state, stage and start.
export function liveJobLine(job, started) {
  return ` ${job.method} · ${jobState(job)} · started ${started}`;
}
