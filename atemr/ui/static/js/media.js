// Media page: "MORE" fetches the next ten items of a kind, rendered by the server with the same template as the
// page (thumbnail, player, download, delete that asks first), and appends them.
"use strict";

(function () {
  for (const btn of document.querySelectorAll("button.more")) {
    btn.addEventListener("click", async () => {
      const kind = btn.dataset.kind;
      const list = document.querySelector(`#${kind} ul.files`);
      const offset = list.querySelectorAll("li[data-name]").length;
      btn.disabled = true;
      try {
        const r = await fetch(`/media/${encodeURIComponent(kind)}/more?offset=${offset}`);
        if (!r.ok) return;
        list.insertAdjacentHTML("beforeend", await r.text());
        const total = Number(r.headers.get("X-Total-Count"));
        if (list.querySelectorAll("li[data-name]").length >= total) btn.remove();
      } finally {
        btn.disabled = false;
      }
    });
  }
})();
