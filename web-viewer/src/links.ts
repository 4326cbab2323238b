// Links: `?session=sessions/ID#edit=EDIT&view=VIEW` (editor) and
// `?session=sessions/ID&watch=1#view=VIEW` (watch only). The tokens live in the fragment,
// which browsers never send to a server (nor do proxies log it); docs/viewer.md "Links".
import { tokens } from "./api";

export function tokenFragment(edit: string, view: string): string {
  const f = new URLSearchParams();
  if (edit) f.set("edit", edit);
  if (view) f.set("view", view);
  return f.toString();
}

/** What the page's address asks for: a session, its tokens, and whether only to watch. */
export function readPageLink(): { session: string; edit: string; view: string; watchOnly: boolean } {
  const params = new URLSearchParams(window.location.search);
  const fragment = new URLSearchParams(window.location.hash.replace(/^#/, ""));
  let edit = fragment.get("edit") ?? "";
  let view = fragment.get("view") ?? "";
  if (params.has("edit") || params.has("view")) {
    // A hand-made link with a token in the query: use it, but move it out of the address
    // bar's query (it has been sent to the server once already; it goes no further from here).
    edit ||= params.get("edit") ?? "";
    view ||= params.get("view") ?? "";
    params.delete("edit");
    params.delete("view");
    const url = new URL(window.location.href);
    url.search = params.toString();
    url.hash = tokenFragment(edit, view);
    history.replaceState(null, "", url);
  }
  const session = params.get("session") ?? "";
  // A page opened on a session without its edit token is watch-only whatever else its URL
  // says (the server would refuse every edit anyway); `watch=1` also makes an editor's page so.
  const watchOnly = session !== "" && (params.get("watch") === "1" || edit === "");
  return { session, edit, view, watchOnly };
}

/**
 * The session's editor link (edit and view tokens, so its users can hand out watch links
 * too) or watch link (the view token only); "" when this page lacks the token.
 */
export function shareLink(sessionName: string, watch: boolean): string {
  const { edit, view } = tokens();
  if (!sessionName || (watch ? !view : !edit)) return "";
  const url = new URL(window.location.pathname, window.location.origin);
  url.search = linkQuery(sessionName, watch, window.location.search).toString();
  url.hash = watch ? tokenFragment("", view) : tokenFragment(edit, view);
  return url.toString();
}

/**
 * A share link's query: the session, `watch=1` for a watch link, and this page's frame
 * encoding (`?encoding=`) when it chose one, so whoever opens the link gets the same frames
 * (e.g. float32 on a fast LAN). Nothing else of this page's query goes along.
 */
export function linkQuery(sessionName: string, watch: boolean, currentSearch: string): URLSearchParams {
  const q = new URLSearchParams();
  q.set("session", sessionName);
  if (watch) q.set("watch", "1");
  const encoding = new URLSearchParams(currentSearch).get("encoding");
  if (encoding) q.set("encoding", encoding);
  return q;
}

/** The address bar becomes this session's editor link, so a reload opens it again. */
export function showEditorLink(sessionName: string): void {
  const url = new URL(window.location.href);
  url.searchParams.set("session", sessionName);
  url.searchParams.delete("watch");
  url.hash = tokenFragment(tokens().edit, tokens().view);
  history.replaceState(null, "", url);
}

/**
 * The address bar becomes this session's watch link (the token the page holds is the view
 * token), so a reload opens it watch-only at once and the address no longer says `edit=`.
 */
export function showWatchLink(sessionName: string): void {
  const url = new URL(window.location.href);
  url.search = linkQuery(sessionName, true, window.location.search).toString();
  url.hash = tokenFragment("", tokens().view);
  history.replaceState(null, "", url);
}
