// Programs: the library (upload in parts, select, download, rename, delete) and the
// validation results, each a link to its line in a read-only listing.
import { machine, programs } from "../api";
import { button, fill, h } from "../dom";
import { errorText, time } from "../format";
import { t } from "../i18n";
import { diagnosticsOf, diagText, serverText } from "../server_text";
import { Listing } from "../listing";
import { type Screen, messageLine } from "../screen";
import { type Diagnostic, Severity } from "../gen/cnc/v1/cnc_pb";

/** Bytes per UploadPart (below the 4 MiB message limit). */
const PART_BYTES = 1 << 20;
/** Largest text the screen validates and lists (ValidateProgram is one unary message). */
const VALIDATE_MAX_BYTES = 3 << 20;

export async function downloadText(name: string): Promise<string> {
  const parts: Uint8Array[] = [];
  for await (const c of programs.download({ name })) parts.push(c.data);
  return new TextDecoder().decode(await new Blob(parts as BlobPart[]).arrayBuffer());
}

/** Uploads a file through UploadBegin / UploadPart / UploadFinish (no client streaming). */
export async function upload(name: string, data: Blob, select: boolean, progress: (f: number) => void) {
  const first = new Uint8Array(await data.slice(0, PART_BYTES).arrayBuffer());
  const session = await programs.uploadBegin({
    name,
    select,
    totalBytes: BigInt(data.size),
    data: first,
  });
  for (let off = first.length; off < data.size; off += PART_BYTES) {
    const part = new Uint8Array(await data.slice(off, off + PART_BYTES).arrayBuffer());
    await programs.uploadPart({ id: session.id, offset: BigInt(off), data: part });
    progress(off / data.size);
  }
  return await programs.uploadFinish(session);
}

export function programsScreen(): Screen {
  const msg = messageLine();
  const list = h("table", { class: "list", testid: "program-list" });
  const diags = h("ul", { class: "diags", testid: "diagnostics" });
  const listing = new Listing("program-listing");
  const usage = h("span", { class: "lbl" });
  let chosen = "";

  const file = h("input", { type: "file", testid: "program-upload" });
  file.dataset.least = "operator";
  const selectAfter = h("input", { type: "checkbox", testid: "upload-select" });
  selectAfter.dataset.least = "operator";

  function showDiagnostics(items: Diagnostic[]): void {
    fill(
      diags,
      ...items.map((d) => {
        const sev = d.severity === Severity.ERROR ? "error" : d.severity === Severity.WARNING ? "warning" : "note";
        const a = h("a", { href: "#", class: `diag ${sev}`, "data-line": d.line },
          t("diag.line", { sev: t(`diag.${sev}`), code: d.code, line: d.line, column: d.column,
            block: d.block !== undefined ? ` N${d.block}` : "", message: diagText(d.code, d.message) }));
        a.addEventListener("click", (ev) => {
          ev.preventDefault();
          listing.goto(d.line);
        });
        return h("li", {}, a);
      }),
    );
  }

  async function refresh(): Promise<void> {
    try {
      const lib = await programs.list({});
      usage.textContent = t("prog.usage", { used: (Number(lib.usedBytes) / 1e6).toFixed(1), max: (Number(lib.maxBytes) / 1e6).toFixed(0) });
      fill(
        list,
        h("tr", {}, h("th", {}, t("prog.name")), h("th", {}, t("prog.blocks")), h("th", {}, t("prog.kib")), h("th", {}, t("prog.verdict"))),
        ...lib.programs.map((p) => {
          const tr = h("tr", { "data-name": p.name, title: t("prog.stored", { time: time(p.modifiedUnixMs) }),
            class: [p.name === chosen ? "chosen" : "", p.name === lib.selected ? "selected" : ""].join(" ") },
            h("td", { translate: "no" }, p.name === lib.selected ? `▶ ${p.name}` : p.name),
            h("td", {}, String(p.blocks)),
            h("td", {}, (Number(p.sizeBytes) / 1024).toFixed(1)),
            h("td", { class: p.valid ? "ok" : "err" }, p.valid ? (p.warnings ? t("prog.validWarnings", { n: p.warnings }) : t("prog.valid")) : serverText(p.firstError)),
          );
          tr.addEventListener("click", () => void choose(p.name, Number(p.sizeBytes)));
          return tr;
        }),
      );
    } catch (e) {
      msg.err(errorText(e));
    }
  }

  async function choose(name: string, size: number): Promise<void> {
    chosen = name;
    list.querySelectorAll("tr[data-name]").forEach((r) =>
      r.classList.toggle("chosen", (r as HTMLElement).dataset.name === name));
    if (size > VALIDATE_MAX_BYTES) {
      listing.setText(t("prog.tooLarge", { name, mb: (size / 1e6).toFixed(1) }));
      return fill(diags);
    }
    const text = await downloadText(name);
    listing.setText(text);
    const v = await machine.validateProgram({ text });
    showDiagnostics(v.diagnostics);
  }

  const act = (f: () => Promise<unknown>, done?: string) => () => {
    if (!chosen) return msg.err(t("prog.chooseFirst"));
    f().then(() => { if (done) msg.ok(done); return refresh(); }, (e) => { msg.err(errorText(e)); showDiagnostics(diagnosticsOf(e)); });
  };

  file.addEventListener("change", () => {
    const f = file.files?.[0];
    if (!f) return;
    msg.ok(t("prog.uploading", { name: f.name }));
    upload(f.name, f, selectAfter.checked, (x) => msg.ok(t("prog.uploadingPct", { name: f.name, pct: (x * 100).toFixed(0) })))
      .then((done) => {
        msg.ok(`${t("prog.storedBlocks", { name: f.name, blocks: done.program?.blocks ?? 0 })}${done.selected ? t("prog.andSelected") : ""}`);
        showDiagnostics(done.diagnostics);
        chosen = f.name;
        return refresh();
      })
      .catch((e) => {
        msg.err(`${f.name}: ${errorText(e)}`);
        showDiagnostics(diagnosticsOf(e));
        void f.text().then((t) => listing.setText(t));
      })
      .finally(() => (file.value = ""));
  });

  const rename = h("input", { type: "text", placeholder: t("prog.newName"), testid: "program-rename-to" });
  rename.dataset.least = "operator";
  const el = h(
    "div",
    { class: "screen programs" },
    h(
      "div",
      { class: "row" },
      h("label", { class: "file" }, `${t("prog.upload")} `, file),
      h("label", { class: "check" }, selectAfter, ` ${t("prog.selectAfter")}`),
      usage,
    ),
    h("div", { class: "two" }, h("div", { class: "scroll" }, list), listing.el),
    h(
      "div",
      { class: "row" },
      button(t("prog.select"), "program-select", act(() => machine.selectProgram({ name: chosen }), t("prog.selected"))),
      button(t("prog.download"), "program-download", act(async () => {
        const a = h("a", { href: URL.createObjectURL(new Blob([await downloadText(chosen)])), download: chosen });
        a.click();
      }), "", "observer"),
      rename,
      button(t("prog.rename"), "program-rename", act(async () => {
        await programs.rename({ from: chosen, to: rename.value.trim() });
        chosen = rename.value.trim();
        rename.value = "";
      }, t("prog.renamed"))),
      button(t("prog.delete"), "program-delete", act(async () => {
        if (confirm(t("prog.askDelete", { name: chosen }))) await programs.delete({ name: chosen });
      }, t("prog.deleted")), "danger"),
    ),
    msg.el,
    diags,
  );
  return { id: "programs", el, onShow: () => void refresh() };
}
