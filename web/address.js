// The view kept in the page's address, so that a reload, or the link opened on another device, shows the same
// view: ?drive=/turtle1/cmd_vel&tab=topics&topic=/turtle1/pose&plot=/turtle1/pose:x. Each part of the page
// keeps its own key; the history is not lengthened (replaceState), Back still leaves the page.
export function readAddress(key) {
  return new URLSearchParams(location.search).getAll(key);
}

export function keepInAddress(key, values) {
  const address = new URL(location.href);
  const kept = address.searchParams.getAll(key);
  if (kept.length === values.length && kept.every((value, i) => value === values[i])) return;
  address.searchParams.delete(key);
  for (const value of values) address.searchParams.append(key, value);
  history.replaceState(null, '', address);
}
