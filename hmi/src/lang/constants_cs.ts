// Czech names and meanings of the machine constants the controller reads (the server's table
// kernel::machine::names, in the words of the CNC836/CNC8x9 manuals: "strojní konstanta",
// "dekáda", "plynulá návaznost", "ekvidistanta", "KŘR", "sada pro dynamické řízení rychlosti").
// A constant missing here shows the server's English text.

const axisCode = (k: number) =>
  [`kód ${k}. souřadnice`, `${k}. souřadnice v pořadí stroje: 0 žádná, 1..9 = X Y Z U V W A B C; čte se při startu cncd (SPEC §1)`];

const set = (k: number, g: string): Array<[number, [string, string]]> => {
  const base = 406 + 6 * (k - 1);
  return [
    [base, [`${k}. sada – řídicí slovo`, `${k}. sada pro dynamické řízení rychlosti (G23 I${k}${g}): 1. dekáda = 1 povolena; 2.–6. dekáda = 1: další konstanty odkazují na parametry programu (SPEC §7.4)`]],
    [base + 1, [`${k}. sada – parabolické zrychlení P`, `${k}. sada: parabolické zrychlení P, 10000 měkké..150000 tvrdé; 8. dekáda = 2, 3 dělí 100, 1000 (SPEC §7.3, §7.4)`]],
    [base + 2, [`${k}. sada – lineární zrychlení A`, `${k}. sada: lineární zrychlení A, největší zrychlení (SPEC §7.3, §7.4)`]],
    [base + 3, [`${k}. sada – kritérium přesnosti`, `${k}. sada: kritérium přesnosti Lm (1.–4. dekáda) a procento poklesu rychlosti (5.–6. dekáda), jako R384 (SPEC §7.4)`]],
    [base + 4, [`${k}. sada – kritérium přetížení`, `${k}. sada: dynamické kritérium am, jako R385 (SPEC §7.4)`]],
    [base + 5, [`${k}. sada – odstředivé zrychlení`, `${k}. sada: odstředivé zrychlení na kruhu, 8. dekáda = 1: 1.–7. dekáda / 10 mm/s², jinak starší tvar R232 (SPEC §7.2, §7.4)`]],
  ];
};

export const constantsCs = new Map<number, [string, string]>([
  ...[0, 1, 2, 3, 4, 5].map((r): [number, [string, string]] => {
    const [n, m] = axisCode(r + 1);
    return [r, [n, m]];
  }),
  [6, ["okno G24, souřadnice 1..3", "Odchylka, pod kterou blok G24 souřadnic 1..3 platí za dojetý a začne další (dojetí minimální odchylky) (SPEC §7.1)"]],
  [7, ["okno G24, souřadnice 4..6", "Odchylka, pod kterou blok G24 souřadnic 4..6 platí za dojetý a začne další (dojetí minimální odchylky) (SPEC §7.1)"]],
  [39, ["toleranční úhel plynulé návaznosti", "Největší úhel tečen, při kterém je napojení automaticky plynulé (R97 = 2); doporučeno 60 (SPEC §7.1)"]],
  [52, ["zrychlení do zastavení", "Zrychlení (rampa) po dráze bez plynulé návaznosti (G98, G24) a v plynulé návaznosti, je-li R236 = 0 (SPEC §7)"]],
  [55, ["tolerance středu kružnice", "O kolik smí koncový bod oblouku ležet mimo kružnici (I, J ji předurčují) (SPEC §2)"]],
  [67, ["řídící souřadnice KŘR", "Souřadnice, jejíž poloha dává řezný poloměr konstantní řezné rychlosti: 1..9 = X Y Z U V W A B C (SPEC §6)"]],
  [95, ["poloměrové korekce", "8. dekáda R95 = 1: poloměrové korekce s výpočtem ekvidistanty (G41/G42) povoleny (SPEC §4)"]],
  [97, ["řízení plynulé návaznosti", "1. dekáda R97 = 1: ruční, rozhoduje G23/G24; 2: automatické rozpoznání podle úhlu R39 (SPEC §7.1)"]],
  [232, ["kritérium pro kruhovou interpolaci", "1.–4. dekáda: geometrické kritérium, největší odchylka tětivy od kružnice za takt, µm (0 vypnuto); 5.–8. dekáda: dynamické kritérium, procento (SPEC §7.2)"]],
  [234, ["limit pro test spojitosti", "Pod tímto úhlem tečen se průsečík ekvidistant nepočítá: použije se bod na kolmici (SPEC §4.4)"]],
  [236, ["zrychlení pro plynulou návaznost", "Zrychlení (rampa) po dráze při G23; 0 = R52 (SPEC §7)"]],
  [237, ["zrychlení rychloposuvu", "Zrychlení rychloposuvu G0 (SPEC §7)"]],
  [325, ["zpřesňování kruhové interpolace", "1.–7. dekáda: největší zpřesnění I nebo J preprocesorem (adresa E, nejvýše 3 mm); 8. dekáda: 0 vypnuto, 1 zapnuto, 2 bez testu limitu zpřesnění (SPEC §4.6)"]],
  [329, ["jednotky S, G96/G97", "3. dekáda R329: 0 standard, 1 záměna G96 za G97, 2 S v m/min, 3 obojí (soustruhy) (SPEC §6)"]],
  [338, ["obálková rychlost", "2. dekáda R338: 0 bez obálkové rychlosti, 1 lineární, 2 parabolický průběh (SPEC §7.2, §7.3)"]],
  [339, ["vkládání kroužků pro poloměrové korekce", "8. dekáda: 0 průsečík, 1 oblouk na vnějších rozích nad úhlem z 1.–6. dekády, 2 i při neexistujícím průsečíku, 4 jen tam; 7. dekáda = 1: G40 bez pohybu; záporná: hlásit každý oblouk (SPEC §4.2, §4.3)"]],
  [382, ["délka bloku pro zrušení plynulé návaznosti", "Blok kratší než tato délka přeruší plynulou návaznost; záporná = vypnuto (SPEC §7.2)"]],
  [383, ["délka bloku pro vynechání bloku", "Přímka kratší než tato délka se sloučí se sousedním blokem; záporná = vypnuto (SPEC §7.2)"]],
  [384, ["omezení rychlosti – kritérium přesnosti", "1.–4. dekáda: kritérium přesnosti Lm, vm = Lm/(Ts·tan(α/2)), 0 vypnuto; 5.–6. dekáda: procento poklesu rychlosti pro grafický náhled (červená tečka) (SPEC §7.2, §7.5)"]],
  [385, ["omezení rychlosti – dynamické kritérium", "1.–7. dekáda: dynamické kritérium am, vm = am·Ts/(2·sin(α/2)); 8. dekáda = 1..4: korekce kritéria na délku bloku (SPEC §7.2)"]],
  [387, ["počet bloků pro grafický náhled", "Bloků vykreslených na jednu stranu náhledu; 0 = celý program (SPEC §7.5)"]],
  [395, ["kritérium času pro nárůst rychlosti", "Nárůst rychlosti k F uvnitř bloku jen tehdy, ušetří-li víc než tento čas; 0 = 500 ms (SPEC §7.2, §7.3)"]],
  [397, ["kontrola a optimalizace ekvidistanty", "1. dekáda = 1 kontrola vypnuta, 2. bez upozornění, 3./4. tříbloková/čtyřbloková optimalizace, 5. doplňkové oblouky, 6. přímo G41↔G42, 7./8. vadné oblouky jako přímky (SPEC §4.5)"]],
  ...set(1, ""),
  ...set(2, ", DYNAM_SET 1"),
  ...set(3, ", DYNAM_SET 2"),
  ...set(4, ", DYNAM_SET 3"),
  [430, ["sada pro rychloposuv – řídicí slovo", "1. dekáda R430 = 1: G0 a STOP používají rampu z R431 a R432 (SPEC §7.4)"]],
  [431, ["sada pro rychloposuv – parabolické zrychlení P", "Sada pro rychloposuv a stop pohybu: parabolické zrychlení P, jako R407 (SPEC §7.3, §7.4)"]],
  [432, ["sada pro rychloposuv – lineární zrychlení A", "Sada pro rychloposuv a stop pohybu: lineární zrychlení A (SPEC §7.3, §7.4)"]],
  [580, ["verze konstantní řezné rychlosti", "0: starší verze KŘR, jen pohybové bloky; 1: novější verze, i nepohybové bloky, ruční posuv, PLC, omezení otáček G76 (SPEC §6)"]],
  [764, ["optimalizace výjezdu z tvaru", "1.–3. dekáda: poslední pracovní blok před rychloposuvem kratší než toto procento poloměru (0 = 150 %); 8. dekáda = 1 optimalizovat, 7. dekáda = 1 hlásit (SPEC §4.5)"]],
  [765, ["kontrola polohy ekvidistanty", "1.–3. dekáda: hlásit, kde ekvidistanta leží dál než toto procento poloměru (0 = 300 %); 8. dekáda = 1 optimalizovat, 7. dekáda = 1 hlásit (SPEC §4.5)"]],
]);

/** Units as the constants' table writes them, in Czech words where they are words. */
export function unitCs(unit: string): string {
  return unit.replace("decades", "dekády").replace("code", "kód").replace("blocks", "bloky");
}
