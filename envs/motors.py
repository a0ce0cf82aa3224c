"""Built-in table of stepper motors by the names Klipper users write (``[autotune_tmc stepper_x]
motor: ldo-42sth48-2504ac``), with their five datasheet constants.

Source: the motor database of the ``klipper_tmc_autotune`` plugin (``andrewmcgr/klipper_tmc_autotune``,
``motor_database.cfg``) at commit 3d1ab9f (2026-07-29), as reproduced in
``tests/data/reference/motors.md`` (203 motors). Constants per motor: phase ``resistance`` (Ω),
phase ``inductance`` (H), ``holding_torque`` (N·m at the rated current), ``rated_current`` (A, the
datasheet's per-phase current, the database's ``max_current``) and ``steps_per_revolution``.

Values are the database's, verbatim, including its one evident unit slip
(``ldo-42sth34-1004l321e``: holding torque 107.7, N·cm read as N·m; its ``(prusa-z)`` twin has
0.59): a user who names that motor gets what Klipper's plugin gets. Names are looked up
case-insensitively (Klipper keeps the case the user wrote; the database mixes both).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass


@dataclass(frozen=True)
class MotorConstants:
    """Datasheet constants of a two-phase hybrid stepper (SI units: Ω, H, N·m, A)."""

    name: str
    resistance: float          # Ω per phase
    inductance: float          # H per phase
    holding_torque: float      # N·m at the rated current (two phases energised)
    rated_current: float       # A per phase (datasheet; Klipper autotune's max_current)
    steps_per_revolution: int  # full steps per revolution (200: 1.8°, 400: 0.9°)


#: (name, resistance Ω, inductance H, holding torque N·m, rated current A, steps per revolution)
_ROWS: tuple[tuple[str, float, float, float, float, int], ...] = (
    ('ldo-36sth17-1004ahg',               10.0, 0.006, 0.10, 1.0, 200),
    ('ldo-36sth20-1004ahg-9T',            2.4, 0.0014, 0.10, 1.0, 200),
    ('ldo-36sth20-0804ah(s22)',           1.85, 0.00105, 0.08, 0.8, 200),
    ('ldo-36sth20-1004ahg',               2.1, 0.0016, 0.10, 1.0, 200),
    ('ldo-36sth20-1004ahg-xh',            2.6, 0.0018, 0.095, 1.0, 200),
    ('ldo-35sth52-1504ah',                2.8, 0.0038, 0.37, 1.5, 200),
    ('ldo-35sth52-2004ah(S35)',           1.34, 0.0021, 0.4, 2.0, 200),
    ('ldo-35sth48-1684ah',                1.65, 0.0028, 0.4, 1.68, 200),
    ('ldo-35sth42-0504ah',                13.5, 0.016, 0.165, 0.5, 200),
    ('ldo-36sth17-0354ahg',               10.8, 0.006, 0.06, 0.35, 200),
    ('fysetc-g36hsy4405-6d-1200',         2.4, 0.0017, 0.11, 1.0, 200),
    ('ldo-42sth40-1684cl350et',           1.65, 0.0041, 0.45, 1.68, 200),
    ('ldo-42sth40-1684ac',                1.65, 0.0036, 0.45, 1.68, 200),
    ('ldo-42sth40-1684mac',               1.65, 0.0032, 0.33, 1.68, 400),
    ('ldo-42sth40-2004mah',               1.1, 0.0028, 0.35, 2.0, 400),
    ('ldo-42sth48-1684ac',                1.65, 0.0028, 0.50, 1.68, 200),
    ('ldo-42sth48-1684mah',               1.65, 0.0028, 0.40, 1.68, 400),
    ('ldo-42sth48-2804ah',                0.7, 0.0006, 0.42, 2.8, 200),
    ('ldo-42sth48-2504ac',                1.2, 0.0015, 0.55, 2.5, 200),
    ('ldo-42sth48-2504macf',              1.2, 0.0015, 0.45, 2.5, 400),
    ('ldo-42sth48-2004ac',                1.6, 0.003, 0.59, 2.0, 200),
    ('ldo-42sth48-2004mah',               1.4, 0.002, 0.44, 2.0, 400),
    ('ldo-42sth40-1004a',                 6.5, 0.013, 0.49, 1, 200),
    ('ldo-42sth34-1334ac',                2.0, 0.0034, 0.22, 1.33, 200),
    ('ldo-42sth34-1504mac',               1.5, 0.003, 0.2, 1.5, 400),
    ('ldo-42sth34-1004l321e',             8.00, 0.0095, 107.7, 1.00, 200),
    ('ldo-42sth34-1004l321e(prusa-z)',    8, 0.0095, 0.59, 1.0, 200),
    ('ldo-42sth40-1004mah',               4.1, 0.0115, 0.39, 1, 400),
    ('ldo-42sth20-1004ash',               7.2, 0.007, 0.18, 1, 200),
    ('ldo-42sth20-1004mah',               7.2, 0.0122, 0.16, 1, 400),
    ('ldo-42sth25-1004cl200et',           5.5, 0.007, 0.24, 1, 200),
    ('ldo-42sth25-1404mac',               2.4, 0.0055, 0.20, 1.4, 400),
    ('ldo-42sth25-1004acg',               5.5, 0.007, 0.20, 1, 200),
    ('ldo-42sth60-2004ac',                2.1, 0.0041, 0.85, 2, 200),
    ('ldo-42sth60-2004mac',               1.4, 0.003, 0.6, 2, 400),
    ('ldo-42sth60-2004mah',               1.4, 0.0030, 0.6, 2, 400),
    ('ldo-42sth25-1404ac',                2.4, 0.0055, 0.23, 1.4, 200),
    ('ldo-42sth25-1404mah',               2.4, 0.0055, 0.18, 1.4, 400),
    ('ldo-42sth48-2004mac(s46)',          1.4, 0.0028, 0.49, 2.0, 400),
    ('ldo-42sth47-1684a',                 1.65, 0.0028, 0.50, 1.68, 200),
    ('moons-ms14hs5p4200',                1.34, 0.0021, 0.4, 2.0, 200),
    ('moons-ms14hs5p4150',                2.2, 0.0036, 0.4, 1.5, 200),
    ('moons-cse14hra1l410a',              1.9, 0.00141, 0.1, 1.0, 200),
    ('moons-cse14hra2l410a',              3.6, 0.0038, 0.19, 1.0, 200),
    ('moons-ms17hdbp4200',                1.49, 0.0038, 0.83, 2.0, 200),
    ('moons-ms17hd2p4150',                1.98, 0.0043, 0.50, 1.50, 200),
    ('moons-ms17hd6p4200',                1.3, 0.0029, 0.63, 2.0, 200),
    ('moons-ms17hd6p4150',                2.2, 0.0049, 0.62, 1.5, 200),
    ('moons-le174s-t0804-300-ar3-s-150',  1.75, 0.0028, 0.29, 1.5, 200),
    ('moons-le174s-t0808-200-ar3-s-065',  8.7, 0.0152, 0.054, 0.65, 200),
    ('moons-le172s-t0804-300-cn-01-200',  1.04, 0.0025, 0.48, 2.00, 200),
    ('moons-ms17hd6p420i',                1.3, 0.0027, 0.67, 2.0, 200),
    ('moons-c17hd2024n-01n',              4.1, 0.0085, 0.39, 1.0, 200),
    ('moons-ml23hs8l4550-20',             0.28, 0.00103, 1.5, 5.5, 200),
    ('moons-ml23hs0l4350-000',            0.56, 0.0013, 0.82, 3.5, 200),
    ('omc-14hs20-1504s-c19',              2.0, 0.0028, 0.4, 1.5, 200),
    ('omc-14hs20-1504s',                  2.8, 0.0038, 0.4, 1.5, 200),
    ('omc-14hs11-1004s',                  3.5, 0.0035, 0.125, 1.0, 200),
    ('omc-14hr07-1004vrn',                3.9, 0.002, 0.09, 1.00, 400),
    ('omc-14hs17-0504s',                  15.00, 0.026, 0.23, 0.50, 200),
    ('omc-14hs10-0404s',                  30.00, 0.030, 0.140, 0.40, 200),
    ('omc-14re08-1004s-h',                2.1, 0.0011, 0.1, 1.00, 200),
    ('omc-17he24-2104s',                  1.7, 0.0031, 0.60, 2.1, 200),
    ('omc-17he08-1004s',                  3.6, 0.004, 0.17, 1.00, 200),
    ('omc-17he12-1204s',                  2.5, 0.0033, 0.26, 1.20, 200),
    ('omc-17he19-2004s',                  1.3, 0.0024, 0.55, 2.0, 200),
    ('omc-17he15-1504s',                  2.3, 0.004, 0.42, 1.50, 200),
    ('omc-17hs15-1504s',                  2.30, 0.0044, 0.45, 1.50, 200),
    ('omc-17hs15-1584s-mg10',             1.65, 0.0032, 0.36, 1.58, 200),
    ('omc-17hm08-1204S',                  3.0, 0.0022, 0.11, 1.2, 400),
    ('omc-17hm19-1684S',                  1.65, 0.0041, 0.44, 1.68, 400),
    ('omc-17hm19-2004s',                  1.45, 0.004, 0.46, 2.0, 400),
    ('omc-17hs19-2504s-h',                1.1, 0.0016, 0.55, 2.5, 200),
    ('omc-17hs24-2104s',                  1.6, 0.003, 0.65, 2.1, 200),
    ('omc-17hs16-2004s1',                 1.1, 0.0026, 0.45, 2, 200),
    ('omc-17hs19-2004s1-h',               1.5, 0.0030, 0.59, 2.00, 200),
    ('omc-17hs19-2004s1',                 1.4, 0.003, 0.59, 2, 200),
    ('omc-17hs08-1004s',                  3.70, 0.0045, 0.16, 1.00, 200),
    ('omc-17me15-1504s',                  2.0, 0.0052, 0.30, 1.50, 400),
    ('23hs30-2804s-sg30',                 1.13, 0.0054, 1.89, 2.8, 200),
    ('tmc-qsh4218-35-10-027',             5.30, 0.0066, 0.27, 1.00, 200),
    ('tmc-qsh4218-41-10-035',             4.50, 0.0075, 0.35, 1.00, 200),
    ('tmc-qsh4218-51-10-049',             5.00, 0.008, 0.49, 1.00, 200),
    ('tmc-qsh4218-47-28-040',             0.50, 0.0006, 0.40, 2.80, 200),
    ('fysetc-g36hsy4407-6d-1200a',        13, 0.01, 0.12, 0.5, 200),
    ('fysetc-35hsh7402-24b-60a',          2.8, 0.0055, 0.42, 1.5, 200),
    ('fysetc-42hsc1433b-200n8',           8, 0.01, 0.35, 1, 200),
    ('fysetc-42hsc1404b-200n8',           29, 0.0038, 0.32, 0.4, 200),
    ('TB-3544',                           1.8, 0.0038, 0.50, 1.5, 200),
    ('fysetc-17HS19-2004S-C',             1.4, 0.003, 0.59, 2.0, 200),
    ('fysetc-17HS19-2004S-AB',            1.3, 0.0027, 0.67, 2.0, 200),
    ('fysetc-42HC40-204A-300N84',         1.1, 0.0026, 0.45, 2.0, 200),
    ('fysetc-17D2201Z-22B-500',           6.5, 0.013, 0.49, 1.0, 200),
    ('damencnc-dcnc-nema23-2.0nm',        1.0, 0.0035, 1.8, 3.0, 200),
    ('dfh-14mcrn-1848',                   2.8, 0.0055, 0.42, 1.5, 200),
    ('dfh-14mcrn-1815',                   13.0, 0.0010, 0.12, 0.5, 200),
    ('zyltech-17hd48002h-22b',            1.8, 0.0038, 0.59, 1.7, 200),
    ('siboor-14sth20-1004a',              1.70, 0.0015, 0.12, 1.88, 200),
    ('siboor-35sth52-1204a',              2.3, 0.0035, 0.4, 1.2, 200),
    ('siboor-35hbx904-22b',               2.50, 0.0043, 0.40, 1.50, 200),
    ('siboor-42sth26-0804a',              5.5, 0.0066, 0.26, 1.0, 200),
    ('siboor-42sth40-1684a-300',          1.65, 0.0032, 0.36, 1.68, 200),
    ('siboor-42sth40-2004a',              1.1, 0.0026, 0.45, 2.0, 200),
    ('siboor-42sth48-2504(s45)',          0.9, 0.0016, 0.6, 2.5, 200),
    ('wantai-42byghw811',                 1.25, 0.0018, 0.48, 2.50, 200),
    ('wantai-42byghm810',                 1.0, 0.0018, 0.48, 2.40, 400),
    ('wantai-42byghm208',                 2.1, 0.0059, 0.21, 1.20, 400),
    ('ldo-42sth60-3004ac',                1.1, 0.0023, 0.9, 3.0, 200),
    ('ldo-42sth60-3004mac',               1.1, 0.0035, 0.8, 3.0, 400),
    ('ldo-42sth60-3004ah',                1.0, 0.0016, 0.8, 3.0, 200),
    ('ldo-42sth60-3004mah',               1.0, 0.0023, 0.72, 3.0, 400),
    ('qidi-bj42d29-28v07',                1.4, 0.0026, 0.41, 1.5, 200),
    ('qidi-BJ42D29-22V08',                4.7, 0.011, 0.6, 1.2, 200),
    ('qidi-BJY36D12-04V13',               2.0, 0.0012, 0.09, 1.0, 200),
    ('creality-42-34',                    6.0, 0.006, 0.4, 1.0, 200),
    ('creality-42-40',                    3.6, 0.008, 0.48, 1.0, 200),
    ('creality-42-48',                    5, 0.011, 0.57, 1.0, 200),
    ('creality-42-60',                    1.2, 0.0034, 0.76, 2.00, 200),
    ('BJ42D22-23V01',                     2.8, 0.0069, 0.37, 1.0, 200),
    ('BJ42D09-20V02',                     1.75, 0.003, 0.15, 0.84, 200),
    ('kelimotor-bj42d15-26v09',           6.0, 0.0088, 0.28, 0.84, 200),
    ('kelimotor-bj42d41-14v19',           1.1, 0.0028, 0.650, 2.0, 200),
    ('kelimotor-bj42d22-25v04',           2.9, 0.0060, 0.400, 1.2, 200),
    ('kelimotor-bjy36d13-04v28',          2.0, 0.0012, 0.100, 1.2, 200),
    ('bondtech-42h030h-1504a-001',        2.85, 0.0038, 0.294, 1.5, 200),
    ('bondtech-42H025H-0704A-005',        4.4, 0.0055, 0.16, 0.7, 200),
    ('bondtech-acc01stm41280',            2.37, 0.0012, 0.09, 1.0, 200),
    ('bondtech-acc04stm41213',            2.1, 0.0015, 0.09, 1.0, 200),
    ('orientalmotor-PKP245D23A',          1.12, 0.0029, 0.58, 2.3, 200),
    ('orientalmotor-PKP245D15A',          2.4, 0.0066, 0.58, 1.5, 200),
    ('orientalmotor-PKP235D23A',          0.97, 0.0012, 0.37, 2.3, 200),
    ('orientalmotor-PKP235D15A',          2.4, 0.0026, 0.37, 1.5, 200),
    ('flsun-42bygh718-b-27hqt',           1.70, 0.0042, 0.42, 1.50, 200),
    ('flsun-v400-42',                     18.00, 0.023, 0.284, 0.5, 200),
    ('flsun-v400-36',                     13.00, 0.01, 0.12, 0.5, 200),
    ('shengyang-36byg1204-a-6qht',        2.4, 0.0013, 0.095, 1.0, 200),
    ('honeybadger-42hs48-25044a',         1.6, 0.0018, 0.49, 2.5, 200),
    ('motech-mt-1701hsm140ae',            1.9, 0.0020, 0.127, 1.4, 400),
    ('motech-mt-1702e133g6-365e',         2.1, 0.0025, 0.314, 1.33, 200),
    ('motech-mt-1703hs120ag518e',         3.0, 0.0060, 0.431, 1.2, 200),
    ('motech-mt-1703hsm168re',            1.65, 0.0036, 0.343, 1.68, 400),
    ('motech-mt-1704hsm168re',            1.65, 0.0028, 0.431, 1.68, 400),
    ('motech-mt-1705hs200ae',             2.0, 0.0033, 0.804, 2.0, 200),
    ('motech-mt-1703hs168a',              1.65, 0.0036, 0.45, 1.68, 200),
    ('motech-mt-1702hs133a',              2.1, 0.0025, 0.31, 1.33, 200),
    ('motech-mt-1704hs168a',              1.65, 0.0028, 0.55, 1.68, 200),
    ('motech-mt-2305hs280aw',             1.13, 0.0036, 1.87, 2.80, 200),
    ('motech-mt-2303hs280aw',             0.90, 0.0025, 1.24, 2.80, 200),
    ('BTT-17H4401S',                      2.40, 0.0037, 0.42, 1.50, 200),
    ('ok42sth34-044e-200g',               30.0, 0.037, 0.28, 0.4, 200),
    ('jinkong-jk42hs34-1334',             2.10, 0.0025, 0.2549729, 1.33, 200),
    ('monoprice-42hb34f08ab',             2.20, 0.0025, 0.22, 1.33, 200),
    ('monoprice-17hs4401s',               1.50, 0.0028, 0.40, 1.70, 200),
    ('oukeda-ok35sth52-1504a',            2.80, 0.0038, 0.40, 1.5, 200),
    ('oukeda-ok42sth34-044e',             2.80, 0.0038, 0.40, 1.5, 200),
    ('oukeda-ok42hc40-204a306n84',        1.10, 0.0026, 0.45, 2.00, 200),
    ('oukeda-ok42hc40-1684a-xh',          1.95, 0.0044, 0.45, 1.68, 200),
    ('oukeda-ok42sth47-204a1xh',          1.40, 0.0030, 0.59, 2.0, 200),
    ('oukeda-17hs4401',                   1.5, 0.0028, 0.40, 1.7, 200),
    ('trianglelab-tl-42bygh20',           6.8, 0.0071, 0.21, 1.0, 200),
    ('bj42d29-30v00',                     1.35, 0.003, 0.44, 1.8, 200),
    ('bj42d22-44v26',                     3.6, 0.008, 0.4, 1, 200),
    ('bjd42d22-53v02',                    2.10, 0.0046, 0.40, 1.50, 200),
    ('geetech-d42hs3418-24b22',           1.65, 0.0032, 0.4, 1.68, 200),
    ('usongshine-17hs4401',               2.40, 0.0037, 0.42, 1.50, 200),
    ('usongshine-17hs4401S',              1.5, 0.0028, 0.42, 1.5, 200),
    ('usongshine-17HS8401',               2, 0.0049, 0.20, 1.5, 200),
    ('usongshine-17HS8401S',              1.8, 0.0032, 0.52, 1.7, 200),
    ('usongshine-17hs4023',               4, 0.0032, 0.14, 0.7, 200),
    ('mercury-42byg011-25',               3.4, 0.046, 0.23, 0.33, 200),
    ('cloudray-17CS07A-180E',             1.94, 0.00496, 0.71, 1.8, 200),
    ('act-17hs4417',                      1.5, 0.0028, 0.40, 1.7, 200),
    ('jkong-jk42hS40-1704',               1.65, 0.0032, 0.4, 1.7, 200),
    ('jkong-jk42hs48-1684',               1.65, 0.0028, 0.44, 1.68, 200),
    ('biqu-35BYGF0713-A-10HZT',           2.3, 0.0020, 0.11, 1.5, 200),
    ('biqu-nebula-extruder',              2.40, 0.0017, 0.11, 1.0, 200),
    ('jkong-jk42hw20-10041-04a',          6.8, 0.007, 0.18, 1.0, 200),
    ('hanpose-17HS6401S-0.9',             1.5, 0.0028, 0.7, 1.7, 400),
    ('lkd-42sth48-2004mah',               1.45, 0.002, 0.40, 2.0, 400),
    ('lkd-42sth48-2004ac',                1.65, 0.003, 0.59, 2.0, 200),
    ('toa-35hsh7402-24b-400',             2.8, 0.0055, 0.42, 1.5, 200),
    ('kingroon-kp3s-42-23-titan',         4.00, 0.004, 0.130, 1.00, 200),
    ('kingroon-kp3s-4232-b01943',         5.60, 0.008, 0.360, 1.00, 200),
    ('kingroon-kp3s-42-40',               2.40, 0.0037, 0.420, 1.50, 200),
    ('shengyang-36byg1510-1m-6qt',        1.8, 0.0012, 0.135, 1.5, 200),
    ('shengyang-42bygh1603-a-20dnt',      6.0, 0.0087, 0.280, 0.8, 200),
    ('shengyang-42bygh2265-a-26dnt',      1.05, 0.0019, 0.26, 1.2, 200),
    ('shengyang-42bygh2904-a-24nq1',      1.0, 0.0020, 0.420, 1.5, 200),
    ('shengyang-42bygh3025-3m-25d',       0.4, 0.0006, 0.56, 4.0, 200),
    ('shengyang-42bygh3025-4m-25d',       0.45, 0.0006, 0.56, 4.0, 200),
    ('rattm-17HS8401',                    1.8, 0.0032, 0.52, 1.8, 200),
    ('motionking-17H2A8417',              1.8, 0.0032, 0.52, 1.7, 200),
    ('wantai-36HS2418',                   1.85, 0.00105, 0.13, 1.8, 200),
    ('hanpose-17hs3401',                  2.4, 0.0028, 0.28, 1.3, 200),
    ('hanpose-17hs4401',                  1.50, 0.0028, 0.40, 1.50, 200),
    ('th3d-nema17-pancake',               4.1, 0.0041, 0.13, 1.0, 200),
    ('bozu-42SHDC3025-24B',               4.4, 0.00697, 0.40, 0.9, 200),
    ('leisai-42cm06d',                    0.9, 0.0016, 0.6, 2.5, 200),
    ('leadshine-42cm08',                  1.0, 0.0024, 0.8, 2.5, 200),
    ('longs-17hs5425-06',                 1.0, 0.00175, 0.6, 2.5, 200),
    ('rbmotor-42shdc3030',                2.40, 0.0037, 0.420, 1.50, 200),
    ('tronxy-SL42STH40-1684A',            1.2, 0.0022, 0.380, 1.7, 200),
    ('tronxy-42SHDC4080Z1-25B',           1.5, 0.0028, 0.40, 1.68, 200),
)

#: every built-in motor by its name as written in the database
MOTOR_TABLE: dict[str, MotorConstants] = {r[0]: MotorConstants(*r) for r in _ROWS}
_FOLDED: dict[str, MotorConstants] = {k.casefold(): v for k, v in MOTOR_TABLE.items()}


def lookup_motor(name: str) -> MotorConstants | None:
    """The built-in motor called ``name`` (case-insensitive), or ``None`` when it is not in the table."""
    return _FOLDED.get(str(name).strip().casefold())


def closest_motor_names(name: str, n: int = 3) -> list[str]:
    """Up to ``n`` built-in names most like ``name`` (for "unknown motor, did you mean …")."""
    folded = {k.casefold(): k for k in MOTOR_TABLE}
    hits = difflib.get_close_matches(str(name).strip().casefold(), list(folded), n=n, cutoff=0.5)
    return [folded[h] for h in hits]


def unknown_motor_message(name: str) -> str:
    """One line naming an unknown motor and the closest known names."""
    near = closest_motor_names(name)
    hint = f"; closest known: {', '.join(near)}" if near else ""
    return (f"unknown motor {name!r} (not among the {len(MOTOR_TABLE)} built-in motors{hint}); "
            "give its constants (holding_torque, rated_current, resistance, inductance)")
