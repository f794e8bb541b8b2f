// How the page writes ages and byte counts.
export function formatAge(seconds) {
  return seconds < 1 ? `${Math.max(0, seconds * 1000).toFixed(0)} ms` : `${seconds.toFixed(1)} s`;
}

export function formatBytes(count) {
  if (count >= 1e6) return `${(count / 1e6).toFixed(2)} MB`;
  if (count >= 1e3) return `${(count / 1e3).toFixed(count >= 1e4 ? 0 : 1)} kB`;
  return `${count.toFixed(0)} B`;
}
