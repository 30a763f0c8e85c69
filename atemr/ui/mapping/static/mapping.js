// The Mapping page: BEGIN MAP / END MAP (MANUAL only, the robot decides), the save/discard dialog, map
// selection (switches the active map). The live map comes through the shared map view (map_version).
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const A = window.ATEMR;
  const toggle = $("mapping-toggle"), dialog = $("save-dialog"), select = $("map-select");

  // The robot's own list of maps wins over the files this page was rendered with.
  let knownMaps = "";
  function syncMaps(names) {
    const key = names.join("\n");
    if (key === knownMaps || document.activeElement === select) return;
    knownMaps = key;
    select.innerHTML = "";
    const none = document.createElement("option");
    none.value = ""; none.textContent = "—";
    select.appendChild(none);
    for (const n of names) { const o = document.createElement("option"); o.value = o.textContent = n; select.appendChild(o); }
  }

  A.onState((s) => {
    if (Array.isArray(s.maps)) syncMaps(s.maps);
    toggle.textContent = s.mapping ? "END MAP" : "BEGIN MAP";
    toggle.classList.toggle("on", !!s.mapping);
    if (s.active_map && select.value !== s.active_map && document.activeElement !== select) {
      if ([...select.options].some((o) => o.value === s.active_map)) select.value = s.active_map;
    }
  });

  toggle.addEventListener("click", async () => {
    if (A.state.mapping) {
      const ack = await A.command("mapping_end");
      if (ack.ok) { $("save-name").value = ""; dialog.showModal(); }
    } else {
      await A.command("mapping_begin");
    }
  });

  $("save-form").addEventListener("submit", async (e) => {
    e.preventDefault();
    const action = e.submitter ? e.submitter.value : "save";
    if (action === "discard") {
      const ack = await A.command("map_discard");
      if (ack.ok) dialog.close();
      return;
    }
    const name = $("save-name").value.trim();
    const ack = await A.command("map_save", { name });
    if (ack.ok) {
      dialog.close();
      if (!Array.isArray(A.state.maps)) setTimeout(() => location.reload(), 300); // refresh the file list
    }
  });

  select.addEventListener("change", () => { if (select.value) A.command("map_select", { name: select.value }); });
})();
