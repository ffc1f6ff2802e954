// Czech texts of the daemon's alarm and fault messages. An alarm carries no code of its own
// (cnc.v1.Alarm has a source and a text): the texts come from fixed sentences of the daemon
// (hal::FaultReason, the I/O alarms, the job journal), so each is recognised by its pattern
// and said in Czech with the numbers and names it carries. A text no pattern knows is shown
// as the server wrote it.
type Rule = [RegExp, string];

const RULES: Rule[] = [
  [/^axis (\S+), /, "osa $1, "],
  [/^spindle, /, "vřeteno, "],
  [/node (\d+), /, "uzel $1, "],
  [/following error too large \(axis blocked, too fast, or drive too weak\)/, "příliš velká odchylka polohy (osa zablokovaná, příliš rychlý pohyb nebo slabý pohon)"],
  [/no feedback from the drive in time \(drive off, cable, or drive not answering\)/, "pohon neodpověděl včas (pohon vypnut, kabel nebo pohon neodpovídá)"],
  [/drive heartbeat lost \(drive switched off, reset, or cable disconnected\)/, "ztráta hlídacího signálu pohonu (pohon vypnut, resetován nebo odpojen kabel)"],
  [/bus error \(interface down or not writable\)/, "chyba sběrnice (rozhraní vypnuto nebo nelze zapisovat)"],
  [/CAN bus-off \(check the wiring, termination and baud rate\)/, "sběrnice CAN odpojena (zkontrolujte zapojení, zakončení a přenosovou rychlost)"],
  [/too many CAN error frames \(check the wiring, termination and baud rate\)/, "příliš mnoho chybových rámců CAN (zkontrolujte zapojení, zakončení a přenosovou rychlost)"],
  [/drive fault \(code (\w+), see the drive manual\)/, "porucha pohonu (kód $1, viz návod k pohonu)"],
  [/drive fault: (.*) \(code (\w+)\)/, "porucha pohonu: $1 (kód $2)"],
  [/drive did not answer its configuration \(object ([^)]*)\)/, "pohon neodpověděl na nastavení (objekt $1)"],
  [/drive refused its configuration \(object (.*)\)$/, "pohon odmítl nastavení (objekt $1)"],
  [/process data of wrong length \(COB-ID (\w+): (\d+) bytes, the mapping gives (\d+); check the drive's PDO mapping\)/, "procesní data chybné délky (COB-ID $1: $2 bajtů, mapování dává $3; zkontrolujte mapování PDO pohonu)"],
  [/drive did not start after reset \(powered\? node id set right\?\)/, "pohon po resetu nenaběhl (napájení? správné číslo uzlu?)"],
  [/drive did not switch on \(statusword (\w+); safe torque off or no power\?\)/, "pohon se nezapnul (stavové slovo $1; bezpečné vypnutí momentu nebo chybí napájení?)"],
  [/drive switched itself off \(statusword (\w+); safe torque off or quick stop\?\)/, "pohon se sám vypnul (stavové slovo $1; bezpečné vypnutí momentu nebo rychlé zastavení?)"],
  [/drive left operation \((.*); it was restarted or stopped\)/, "pohon opustil provoz ($1; byl restartován nebo zastaven)"],
  [/serial link lost \(port closed or unplugged\)/, "sériová linka ztracena (port zavřen nebo odpojen)"],
  [/serial replies corrupt \(check the cable, shielding and baud rate\)/, "poškozené odpovědi sériové linky (zkontrolujte kabel, stínění a přenosovou rychlost)"],
  [/reference run failed in the drive \(statusword (\w+): .*\)/, "najíždění reference v pohonu selhalo (stavové slovo $1: nenalezen referenční spínač, koncový spínač nebo nepodporovaná metoda)"],
  [/reference run did not end in time \(.*\)/, "najíždění reference neskončilo včas (referenční spínač nedosažen nebo pohon nepotvrdil referenční bod; viz homing_timeout_ms)"],
  [/drive refused the reference position of the reference run \(home again\)/, "pohon odmítl referenční bod (najeďte referenci znovu)"],
  [/drive unit speaks serial protocol version (\d+), .* needs version (\d+) \(.*\)/, "pohon používá sériový protokol verze $1, potřebná je verze $2 (aktualizujte jednotku)"],
  [/emergency stop: the e-stop chain is open \(release the button, then Reset\)/, "nouzový stop: obvod nouzového stopu je rozpojen (uvolněte tlačítko, pak Nulování)"],
  [/hardware limit switch reached on the positive side \(after Reset jog away from it\)/, "dosažen koncový spínač v kladném směru (po Nulování odjeďte ručně)"],
  [/hardware limit switch reached on the negative side \(after Reset jog away from it\)/, "dosažen koncový spínač v záporném směru (po Nulování odjeďte ručně)"],
  [/alarm input (\S+) active \(see the machine's I\/O list\)/, "alarmový vstup $1 aktivní (viz seznam vstupů a výstupů stroje)"],
  [/alarm input (\S+): /, "alarmový vstup $1: "],
  [/\[input (\S+)\]/, "[vstup $1]"],
  [/^input (\S+) active$/, "vstup $1 aktivní"],
  [/io_wait_timeout: input (\S+) did not confirm within (\d+) ms; the program holds \(Resume waits again\)/, "vstup $1 nepotvrdil do $2 ms; program stojí (Pokračovat čeká znovu)"],
  [/^constant cutting speed: /, "konstantní řezná rychlost: "],
  [/cncd ended during program (.*) \(job (\d+), started (.*)\): last at block (\S+), line (\d+); check the part and the tool, then run it again/, "cncd skončil během programu $1 (úloha $2, start $3): naposledy v bloku $4, řádek $5; zkontrolujte obrobek a nástroj a spusťte jej znovu"],
];

/** The alarm text in Czech where its pattern is known; otherwise the server's text. */
export function alarmCs(text: string): string {
  let s = text;
  for (const [re, cs] of RULES) s = s.replace(re, cs);
  return s;
}

/** Where an alarm comes from (cnc.v1.Alarm.source), in Czech. */
export function alarmSourceCs(source: string): string {
  const [kind, name] = source.split(":", 2);
  const words: Record<string, string> = {
    drive: "pohon",
    planner: "plánovač",
    offsets_file: "soubor korekcí",
    constants_file: "soubor konstant",
    work_offsets_file: "soubor nulových bodů",
    interrupted_job: "přerušená úloha",
    input: "vstup",
    wait: "čekání na vstup",
  };
  const w = words[kind];
  return w ? (name ? `${w} ${name}` : w) : source;
}
