// Media page: "MORE" fetches the next ten of a kind and appends them with download and delete.
"use strict";

(function () {
  const csrf = (document.querySelector('meta[name="csrf-token"]') || {}).content || "";
  for (const btn of document.querySelectorAll("button.more")) {
    btn.addEventListener("click", async () => {
      const kind = btn.dataset.kind;
      const list = document.querySelector(`#${kind} ul.files`);
      const offset = list.querySelectorAll("li[data-name]").length;
      const r = await fetch(`/api/media/${kind}?offset=${offset}`, { headers: { Accept: "application/json" } });
      if (!r.ok) return;
      const body = await r.json();
      for (const f of body.files) {
        const li = document.createElement("li");
        li.dataset.name = f.name;
        const a = document.createElement("a");
        a.href = `/media/${kind}/${encodeURIComponent(f.name)}`; a.className = "download"; a.textContent = f.name;
        const size = document.createElement("small");
        size.textContent = ` ${(f.size_bytes / 1024).toFixed(1)} KiB `;
        const form = document.createElement("form");
        form.method = "post"; form.className = "inline";
        form.action = `/media/${kind}/${encodeURIComponent(f.name)}/delete`;
        const token = document.createElement("input");
        token.type = "hidden"; token.name = "csrf_token"; token.value = csrf;
        const del = document.createElement("button");
        del.type = "submit"; del.className = "danger delete-one"; del.textContent = "DELETE";
        form.append(token, del);
        if (f.builtin) {
          const tag = document.createElement("small");
          tag.className = "builtin"; tag.textContent = "built-in";
          li.append(a, size, tag);  // read-only: the map store refuses to delete it
        } else {
          li.append(a, size, form);
        }
        list.appendChild(li);
      }
      if (offset + body.files.length >= body.total) btn.remove();
    });
  }
})();
