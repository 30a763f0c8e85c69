// The Routines page follows the robot while it is open: a routine that starts, ends or is skipped (the robot's
// "routine" event) brings its lists back from the server, so "next run" and "Last runs" do not wait for a
// reload; once a minute too, for "it is now" and the next runs past midnight. The form is left as typed.
"use strict";

(function () {
  const A = window.ATEMR;
  const PARTS = ["routines-live", "routine-history"]; // the list with the next runs, the last runs
  let busy = false;

  async function refresh() {
    if (busy || document.hidden) return;
    busy = true;
    try {
      const answer = await fetch(location.pathname, { credentials: "same-origin", headers: { Accept: "text/html" } });
      if (!answer.ok) return; // logged out or the robot gone: the status bar says so
      const fresh = new DOMParser().parseFromString(await answer.text(), "text/html");
      for (const id of PARTS) {
        const now = fresh.getElementById(id);
        const old = document.getElementById(id);
        if (now && old) old.replaceWith(document.importNode(now, true));
      }
      document.body.dataset.routinesRefreshed = String(Date.now()); // for tests: the lists came back
    } catch (err) {
      console.warn("routines: could not refresh", err);
    } finally {
      busy = false;
    }
  }

  A.onEvent((e) => { if (e.kind === "routine") refresh(); });
  setInterval(refresh, 60_000);
})();
